"""Writes examples/meshes/swaying.glb: three reeds swaying on skinned joint chains and a jelly blob squashing by a
morph target, as one glTF file with its own camera, lights and animation (`wgpu-rt render
examples/meshes/swaying.glb --frames 0:49 --temporal --out sway/{frame:03d}.png`).

Each reed is a tapered tube of 24 rings skinned to a chain of four joints a quarter of its height apart (each vertex
shared between the two joints about its height, linearly); every joint above the root turns to and fro about two
axes, each reed at its own phase, so the reeds bend rather than tilt. The blob is an icosphere with one morph target,
itself squashed onto the floor (0.65 as tall, 1.25 as wide), its weight going 0 → 1 → 0 twice. 2 s at 24 frames a
second: 49 frames; a still camera, a low sun and a cool fill light. Run from the repository root:
    python examples/meshes/make_swaying.py
"""

from pathlib import Path

import numpy as np
import trimesh
from make_gallery import add_accessor, join_glb, look_rotation, split_glb   # (this folder is on the path)
from trimesh.visual.material import PBRMaterial

HERE = Path(__file__).parent
OUT = HERE / "swaying.glb"
SECONDS = 2.0
KEYS = 25                          # keyframes over the animation (every 1/12 s)
JOINTS = 4                         # per reed, from its root up
RINGS, SECTIONS = 24, 16
# (base position, height, base radius, material, phase)
REEDS = [((-0.55, 0.0, -0.2), 1.3, 0.07, "green", 0.0),
         ((-0.15, 0.0, -0.45), 1.4, 0.08, "copper", 1.9),
         ((0.2, 0.0, -0.15), 1.1, 0.06, "green", 3.7)]
BLOB_CENTRE, BLOB_RADIUS = np.array([0.55, 0.3, 0.25]), 0.3


def tube(height: float, radius: float) -> trimesh.Trimesh:
    """A closed-top tube standing on y = 0, tapering to a third of its ``radius`` at ``height``, smooth normals."""
    heights = np.linspace(0.0, height, RINGS)
    radii = radius * (1.0 - heights / height * 2 / 3)
    angles = np.linspace(0, 2 * np.pi, SECTIONS, endpoint=False)
    rings = [np.column_stack([r * np.cos(angles), np.full(SECTIONS, y), r * np.sin(angles)])
             for y, r in zip(heights, radii)]
    vertices = np.concatenate([*rings, [[0.0, height, 0.0]]])
    faces = []
    for k in range(RINGS - 1):
        for s in range(SECTIONS):
            a, b = k * SECTIONS + s, k * SECTIONS + (s + 1) % SECTIONS
            faces += [[a, b + SECTIONS, b], [a, a + SECTIONS, b + SECTIONS]]
    top, cap = len(vertices) - 1, (RINGS - 1) * SECTIONS
    faces += [[cap + s, top, cap + (s + 1) % SECTIONS] for s in range(SECTIONS)]
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.fix_normals()
    return trimesh.Trimesh(vertices, mesh.faces, vertex_normals=mesh.vertex_normals, process=False)


def reed_skin(vertices: np.ndarray, height: float) -> tuple[np.ndarray, np.ndarray]:
    """Per vertex its two joints (JOINTS_0, uint16) and their weights (WEIGHTS_0): linear between the joints below
    and above its height."""
    position = np.clip(vertices[:, 1] / (height / JOINTS), 0, JOINTS - 1)
    below = np.minimum(np.floor(position).astype(np.uint16), JOINTS - 1)
    above = np.minimum(below + 1, JOINTS - 1)
    share = position - below
    joints = np.zeros((len(vertices), 4), np.uint16)
    weights = np.zeros((len(vertices), 4), np.float32)
    joints[:, 0], joints[:, 1] = below, above
    weights[:, 0], weights[:, 1] = 1 - share, share
    weights[above == below, :2] = [1, 0]
    return joints, weights


def sway(t: np.ndarray, phase: float, level: int) -> np.ndarray:
    """(len(t), 4) quaternions (x, y, z, w) of a joint ``level`` above the root: to and fro about z, less about x."""
    about_z = 0.22 * np.sin(2 * np.pi * t / SECONDS * 2 + phase + 0.5 * level)
    about_x = 0.07 * np.sin(2 * np.pi * t / SECONDS + 1.3 * phase)
    turn = [trimesh.transformations.quaternion_multiply(trimesh.transformations.quaternion_about_axis(z, (0, 0, 1)),
                                                        trimesh.transformations.quaternion_about_axis(x, (1, 0, 0)))
            for z, x in zip(about_z, about_x)]
    return np.array([[x, y, z, w] for w, x, y, z in turn])


def squashed(sphere: trimesh.Trimesh) -> trimesh.Trimesh:
    """The blob flattened onto its lowest point: 0.65 as tall and 1.25 as wide."""
    vertices = sphere.vertices * [1.25, 1.0, 1.25]
    vertices[:, 1] = -BLOB_RADIUS + (vertices[:, 1] + BLOB_RADIUS) * 0.65
    return trimesh.Trimesh(vertices, sphere.faces, process=False)


def build() -> bytes:
    materials = {
        "green": PBRMaterial(name="reed", baseColorFactor=[0.25, 0.55, 0.18, 1], metallicFactor=0.0,
                             roughnessFactor=0.5),
        "copper": PBRMaterial(name="copper", baseColorFactor=[0.95, 0.64, 0.54, 1], metallicFactor=1.0,
                              roughnessFactor=0.3),
        "jelly": PBRMaterial(name="jelly", baseColorFactor=[0.85, 0.12, 0.15, 1], metallicFactor=0.0,
                             roughnessFactor=0.15),
        "floor": PBRMaterial(name="floor", baseColorFactor=[0.62, 0.6, 0.56, 1], metallicFactor=0.0,
                             roughnessFactor=0.8)}
    scene = trimesh.Scene()
    floor = trimesh.creation.box(extents=(8, 0.02, 8),
                                 transform=trimesh.transformations.translation_matrix((0, -0.01, 0)))
    floor.visual = trimesh.visual.TextureVisuals(uv=np.zeros((len(floor.vertices), 2)), material=materials["floor"])
    scene.add_geometry(floor, node_name="floor", geom_name="floor")
    reeds = []
    for index, (base, height, radius, material, phase) in enumerate(REEDS):
        mesh = tube(height, radius)
        mesh.apply_translation(base)     # bound in place: the skin's inverse bind matrices undo each joint's
        mesh.visual = trimesh.visual.TextureVisuals(uv=np.zeros((len(mesh.vertices), 2)),
                                                    material=materials[material])
        scene.add_geometry(mesh, node_name=f"reed-{index}", geom_name=f"reed-{index}")
        reeds.append((mesh, base, height, phase))
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=BLOB_RADIUS)
    blob = trimesh.Trimesh(sphere.vertices, sphere.faces, vertex_normals=sphere.vertex_normals, process=False)
    blob.visual = trimesh.visual.TextureVisuals(uv=np.zeros((len(blob.vertices), 2)), material=materials["jelly"])
    scene.add_geometry(blob, node_name="blob", geom_name="blob",
                       transform=trimesh.transformations.translation_matrix(BLOB_CENTRE))
    tree, binary = split_glb(scene.export(file_type="glb"))

    def accessor(values, kind: str, dtype=np.float32, bounds: bool = False) -> int:
        return add_accessor(tree, binary, values, kind, dtype, bounds)

    names = [node.get("name") for node in tree["nodes"]]
    times = np.linspace(0.0, SECONDS, KEYS)
    key_times = accessor(times, "SCALAR")
    samplers, channels, skins = [], [], []
    for index, (mesh, base, height, phase) in enumerate(reeds):
        node = names.index(f"reed-{index}")
        first = len(tree["nodes"])
        step = height / JOINTS
        tree["nodes"] += [{"name": f"reed-{index}-joint-{level}",
                           "translation": list(base) if level == 0 else [0.0, step, 0.0],
                           **({"children": [first + level + 1]} if level < JOINTS - 1 else {})}
                          for level in range(JOINTS)]
        tree["scenes"][0]["nodes"].append(first)
        binds = [trimesh.transformations.translation_matrix(-np.asarray(base) - [0, level * step, 0])
                 for level in range(JOINTS)]
        inverse_binds = accessor(np.stack(binds).transpose(0, 2, 1).reshape(JOINTS, 16), "MAT4")
        skins.append({"joints": list(range(first, first + JOINTS)), "inverseBindMatrices": inverse_binds,
                      "skeleton": first})
        tree["nodes"][node]["skin"] = len(skins) - 1
        joints, weights = reed_skin(np.asarray(mesh.vertices) - base, height)
        primitive = tree["meshes"][tree["nodes"][node]["mesh"]]["primitives"][0]
        primitive["attributes"]["JOINTS_0"] = accessor(joints, "VEC4", np.uint16)
        primitive["attributes"]["WEIGHTS_0"] = accessor(weights, "VEC4")
        for level in range(1, JOINTS):
            samplers.append({"input": key_times, "output": accessor(sway(times, phase, level), "VEC4")})
            channels.append({"sampler": len(samplers) - 1, "target": {"node": first + level, "path": "rotation"}})
    tree["skins"] = skins
    blob_node = names.index("blob")
    flat = squashed(blob)
    blob_mesh = tree["meshes"][tree["nodes"][blob_node]["mesh"]]
    blob_mesh["primitives"][0]["targets"] = [
        {"POSITION": accessor(flat.vertices - blob.vertices, "VEC3", bounds=True),
         "NORMAL": accessor(flat.vertex_normals - blob.vertex_normals, "VEC3")}]
    blob_mesh["weights"] = [0.0]
    samplers.append({"input": key_times, "output": accessor(np.sin(2 * np.pi * times / SECONDS) ** 2, "SCALAR")})
    channels.append({"sampler": len(samplers) - 1, "target": {"node": blob_node, "path": "weights"}})
    tree["animations"] = [{"name": "sway", "samplers": samplers, "channels": channels}]

    eye, target = np.array([0.2, 0.95, 2.6]), [0.0, 0.55, -0.1]
    tree["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.62, "aspectRatio": 1.0, "znear": 0.05}}]
    tree["extensions"] = {"KHR_lights_punctual": {"lights": [
        {"type": "directional", "name": "sun", "color": [1.0, 0.93, 0.82], "intensity": 3000.0},
        {"type": "point", "name": "fill", "color": [0.75, 0.85, 1.0], "intensity": 1800.0}]}}
    tree["extensionsUsed"] = sorted(set(tree.get("extensionsUsed", [])) | {"KHR_lights_punctual"})
    first = len(tree["nodes"])
    tree["nodes"] += [
        {"name": "camera", "camera": 0, "translation": eye.tolist(), "rotation": look_rotation(eye, target)},
        {"name": "sun", "extensions": {"KHR_lights_punctual": {"light": 0}},
         "rotation": look_rotation([2.5, 2.0, 1.5], [0.0, 0.0, 0.0])},
        {"name": "fill", "extensions": {"KHR_lights_punctual": {"light": 1}}, "translation": [-1.8, 2.2, 2.0]}]
    tree["scenes"][0]["nodes"] += list(range(first, first + 3))
    return join_glb(tree, binary)

if __name__ == "__main__":
    OUT.write_bytes(build())
    print(f"wrote {OUT} ({OUT.stat().st_size} bytes)")
