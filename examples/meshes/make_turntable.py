"""Writes examples/meshes/turntable.glb: a worn brass box turning on a stone plinth while the camera eases in, as one
glTF file with its own camera, lights and animation (`wgpu-rt render examples/meshes/turntable.glb --frames 0:49
--temporal --out turn/{frame:03d}.png`).

The box wears the worn-metal example's textures as a glTF material would: patina.png as its base colour and
patina-metal-rough.png as its metallic-roughness texture (green roughness, blue metalness), so it is brass with
blotches of green patina per texel. It turns once about its vertical axis in 2 s (keys every quarter turn, slerped)
while the camera moves in along its line of sight (LINEAR), 49 frames at 24 a second; frame 0 is the file's rest
pose. A low sun from the left and a dim fill light. Run from the repository root:
    python examples/meshes/make_turntable.py
"""

from pathlib import Path

import numpy as np
import trimesh
from make_gallery import add_accessor, join_glb, look_rotation, split_glb   # (this folder is on the path)
from PIL import Image
from trimesh.visual.material import PBRMaterial

HERE = Path(__file__).parent
OUT = HERE / "turntable.glb"
TEXTURES = HERE.parent / "textures"
TURN_SECONDS = 2.0
# trimesh's cylinders stand along z: turned to stand along y, their middle at y = 0.25
UPRIGHT_AT_QUARTER_HEIGHT = trimesh.transformations.concatenate_matrices(
    trimesh.transformations.translation_matrix((0, 0.25, 0)),
    trimesh.transformations.rotation_matrix(np.pi / 2, (1, 0, 0)))


def textured_box(extents) -> trimesh.Trimesh:
    """A box of 24 vertices (four a face), each face showing the whole texture upright."""
    half = np.asarray(extents, float) / 2
    faces, vertices, uvs = [], [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            normal = np.zeros(3)
            normal[axis] = sign
            u_axis = np.roll(np.eye(3)[axis], 1) if axis != 1 else np.array([1.0, 0.0, 0.0])
            v_axis = np.cross(normal, u_axis)
            corners = [normal * half + su * u_axis * half + sv * v_axis * half
                       for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
            first = len(vertices)
            vertices += corners
            uvs += [(0, 0), (1, 0), (1, 1), (0, 1)]
            faces += [[first, first + 1, first + 2], [first, first + 2, first + 3]]
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.fix_normals()
    mesh.visual = trimesh.visual.TextureVisuals(uv=np.asarray(uvs, float))
    return mesh


def plain(mesh: trimesh.Trimesh, material: PBRMaterial) -> trimesh.Trimesh:
    mesh.visual = trimesh.visual.TextureVisuals(uv=np.zeros((len(mesh.vertices), 2)), material=material)
    return mesh


def build() -> bytes:
    floor = PBRMaterial(name="floor", baseColorFactor=[0.55, 0.55, 0.58, 1], metallicFactor=0.0, roughnessFactor=0.7)
    stone = PBRMaterial(name="stone", baseColorFactor=[0.8, 0.78, 0.72, 1], metallicFactor=0.0, roughnessFactor=0.9)
    brass = PBRMaterial(name="brass", baseColorTexture=Image.open(TEXTURES / "patina.png").convert("RGB"),
                        metallicRoughnessTexture=Image.open(TEXTURES / "patina-metal-rough.png").convert("RGB"),
                        metallicFactor=1.0, roughnessFactor=1.0)
    box = textured_box((0.6, 0.4, 0.4))
    box.visual.material = brass
    box.apply_translation((0, 0.2, 0))
    parts = {
        "floor": plain(trimesh.creation.box(extents=(8, 0.02, 8), transform=trimesh.transformations
                                            .translation_matrix((0, -0.01, 0))), floor),
        "plinth": plain(trimesh.creation.cylinder(0.55, 0.5, sections=48, transform=UPRIGHT_AT_QUARTER_HEIGHT), stone),
    }
    scene = trimesh.Scene()
    for name, mesh in parts.items():
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    scene.add_geometry(box, node_name="brass-box", geom_name="brass-box",
                       transform=trimesh.transformations.translation_matrix((0, 0.5001, 0)))
    tree, binary = split_glb(scene.export(file_type="glb"))

    def accessor(values, kind: str) -> int:
        return add_accessor(tree, binary, values, kind)

    turn_times = accessor(np.linspace(0, TURN_SECONDS, 5), "SCALAR")
    angles = np.linspace(0, 2 * np.pi, 5)
    turns = accessor([[0, np.sin(a / 2), 0, np.cos(a / 2)] for a in angles], "VEC4")
    start, end, target = np.array([1.3, 1.2, 2.5]), np.array([0.9, 0.95, 1.6]), [0.0, 0.6, 0.0]
    dolly_times = accessor([0.0, TURN_SECONDS], "SCALAR")
    dolly = accessor([start, end], "VEC3")
    names = [node.get("name") for node in tree["nodes"]]
    tree["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.55, "aspectRatio": 1.0, "znear": 0.05}}]
    tree["extensions"] = {"KHR_lights_punctual": {"lights": [
        {"type": "directional", "name": "sun", "color": [1.0, 0.95, 0.85], "intensity": 3500.0},
        {"type": "point", "name": "fill", "color": [0.8, 0.85, 1.0], "intensity": 2500.0}]}}
    tree["extensionsUsed"] = sorted(set(tree.get("extensionsUsed", [])) | {"KHR_lights_punctual"})
    first = len(tree["nodes"])
    tree["nodes"] += [
        {"name": "camera", "camera": 0, "translation": start.tolist(), "rotation": look_rotation(start, target)},
        {"name": "sun", "extensions": {"KHR_lights_punctual": {"light": 0}},
         "rotation": look_rotation([-3.0, 2.5, 1.0], [0.0, 0.0, 0.0])},
        {"name": "fill", "extensions": {"KHR_lights_punctual": {"light": 1}}, "translation": [1.5, 2.5, 2.5]}]
    tree["scenes"][tree.get("scene", 0)]["nodes"] += list(range(first, first + 3))
    tree["animations"] = [{"name": "turn", "samplers": [
        {"input": turn_times, "output": turns, "interpolation": "LINEAR"},
        {"input": dolly_times, "output": dolly, "interpolation": "LINEAR"}], "channels": [
        {"sampler": 0, "target": {"node": names.index("brass-box"), "path": "rotation"}},
        {"sampler": 1, "target": {"node": first, "path": "translation"}}]}]
    return join_glb(tree, binary)

if __name__ == "__main__":
    OUT.write_bytes(build())
    print(f"wrote {OUT} ({OUT.stat().st_size} bytes)")
