"""Writes examples/meshes/gallery.glb: a small gallery as one glTF file with its own camera and lights, the way a
scene exported from Blender arrives (`wgpu-rt render examples/meshes/gallery.glb`).

A room open towards the camera, a window opening in its left wall; a low sun shining in through it, a spot light over
a plinth and a dim point light; on the plinth a rough gold ball, on the floor in the sun an amber glass ball that
absorbs inside (KHR_materials_volume) and a glossy red torus. (No pane in the window: the tracer's shadow rays
cross thin panes, Mitsuba's stop at them, and a sun, which paths cannot meet by chance, would then light the room
only in ours; without one, Mitsuba's render is the gold.) Run from the repository root:
    python examples/meshes/make_gallery.py
"""

import json
import struct
from pathlib import Path

import numpy as np
import trimesh
from trimesh.visual.material import PBRMaterial

OUT = Path(__file__).with_name("gallery.glb")


def look_rotation(origin, target) -> list[float]:
    """glTF's (x, y, z, w) quaternion that turns a node's −z towards ``target`` from ``origin``, +y kept up."""
    forward = np.subtract(target, origin, dtype=float)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    matrix = np.eye(4)
    matrix[:3, :3] = np.column_stack([right, up, -forward])
    w, x, y, z = trimesh.transformations.quaternion_from_matrix(matrix)
    return [float(x), float(y), float(z), float(w)]


def split_glb(data: bytes) -> tuple[dict, bytearray]:
    """A .glb's JSON tree and its binary chunk (to edit, then ``join_glb``)."""
    length = struct.unpack_from("<I", data, 12)[0]
    binary_at = 20 + length
    return (json.loads(data[20:20 + length]),
            bytearray(data[binary_at + 8:binary_at + 8 + struct.unpack_from("<I", data, binary_at)[0]]))


def add_accessor(tree: dict, binary: bytearray, values, kind: str, dtype=np.float32, bounds: bool = False) -> int:
    """Append ``values`` to ``binary`` as a bufferView and an accessor of ``kind`` (float32, or uint16 joints), with
    min and max where glTF asks for them (key times, or ``bounds``); returns the accessor's index."""
    array = np.ascontiguousarray(values, dtype)
    binary.extend(b"\0" * (-len(binary) % 4))
    tree["bufferViews"].append({"buffer": 0, "byteOffset": len(binary), "byteLength": array.nbytes})
    entry = {"bufferView": len(tree["bufferViews"]) - 1, "componentType": 5123 if dtype == np.uint16 else 5126,
             "count": len(array), "type": kind}
    if kind == "SCALAR" or bounds:
        entry.update(min=np.min(array, 0).reshape(-1).tolist(), max=np.max(array, 0).reshape(-1).tolist())
    tree["accessors"].append(entry)
    binary.extend(array.tobytes())
    return len(tree["accessors"]) - 1


def join_glb(tree: dict, binary: bytearray) -> bytes:
    """The .glb of ``tree`` and ``binary`` (padded to 4 bytes, the buffer's length set)."""
    binary.extend(b"\0" * (-len(binary) % 4))
    tree["buffers"][0]["byteLength"] = len(binary)
    text = json.dumps(tree, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    body = (struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(binary), b"BIN\0")
            + bytes(binary))
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def textured(mesh: trimesh.Trimesh, material: PBRMaterial) -> trimesh.Trimesh:
    mesh.visual = trimesh.visual.TextureVisuals(uv=np.zeros((len(mesh.vertices), 2)), material=material)
    return mesh


def rectangle(width: float, height: float) -> trimesh.Trimesh:
    """A single-sided rectangle in the z = 0 plane facing +z, centred on the origin."""
    w, h = width / 2, height / 2
    return trimesh.Trimesh([[-w, -h, 0], [w, -h, 0], [w, h, 0], [-w, h, 0]], [[0, 1, 2], [0, 2, 3]], process=False)


def placed(mesh: trimesh.Trimesh, angle_deg=0.0, axis=(0, 1, 0), translate=(0, 0, 0)) -> trimesh.Trimesh:
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.radians(angle_deg), axis))
    mesh.apply_translation(translate)
    return mesh


def build() -> bytes:
    plaster = PBRMaterial(name="plaster", baseColorFactor=[0.78, 0.74, 0.68, 1], metallicFactor=0.0, roughnessFactor=1.0)
    oak = PBRMaterial(name="oak", baseColorFactor=[0.45, 0.30, 0.18, 1], metallicFactor=0.0, roughnessFactor=0.55)
    stone = PBRMaterial(name="stone", baseColorFactor=[0.85, 0.85, 0.82, 1], metallicFactor=0.0, roughnessFactor=0.8)
    gold = PBRMaterial(name="gold", baseColorFactor=[1.0, 0.78, 0.34, 1], metallicFactor=1.0, roughnessFactor=0.35)
    amber = PBRMaterial(name="amber", baseColorFactor=[1.0, 0.97, 0.9, 1], metallicFactor=0.0, roughnessFactor=0.0)
    lacquer = PBRMaterial(name="lacquer", baseColorFactor=[0.7, 0.06, 0.05, 1], metallicFactor=0.0, roughnessFactor=0.1)
    parts = {
        "floor": textured(placed(rectangle(6, 6), -90, (1, 0, 0)), oak),
        "back-wall": textured(placed(rectangle(6, 3), 0, translate=(0, 1.5, -2)), plaster),
        "right-wall": textured(placed(rectangle(6, 3), -90, translate=(2.5, 1.5, 0)), plaster),
        "ceiling": textured(placed(rectangle(6, 6), 90, (1, 0, 0), translate=(0, 3, 0)), plaster),
        # the left wall, x = −2 from z = −2 to 3, around a window opening z ∈ [−1.5, 0.7], y ∈ [0.5, 2.1]
        "left-wall-low": textured(placed(rectangle(5, 0.5), 90, translate=(-2.0, 0.25, 0.5)), plaster),
        "left-wall-high": textured(placed(rectangle(5, 0.9), 90, translate=(-2.0, 2.55, 0.5)), plaster),
        "left-wall-back": textured(placed(rectangle(0.5, 1.6), 90, translate=(-2.0, 1.3, -1.75)), plaster),
        "left-wall-front": textured(placed(rectangle(2.3, 1.6), 90, translate=(-2.0, 1.3, 1.85)), plaster),
        "plinth": textured(trimesh.creation.box(extents=(0.7, 0.8, 0.7), transform=trimesh.transformations
                                                .translation_matrix((0.5, 0.4, -0.6))), stone),
        "gold-ball": textured(placed(trimesh.creation.icosphere(3, radius=0.25), translate=(0.5, 1.05, -0.6)), gold),
        "amber-ball": textured(placed(trimesh.creation.icosphere(3, radius=0.3), translate=(-0.45, 0.3, 0.1)), amber),
        "torus": textured(placed(trimesh.creation.torus(0.28, 0.09, major_sections=48, minor_sections=16), 70,
                                 (1, 0, 0), translate=(-0.2, 0.36, -1.1)), lacquer),
    }
    scene = trimesh.Scene()
    for name, mesh in parts.items():
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    data = scene.export(file_type="glb")
    length = struct.unpack_from("<I", data, 12)[0]
    tree = json.loads(data[20:20 + length])
    for material in tree["materials"]:
        if material["name"] == "amber":
            material["extensions"] = {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                                      "KHR_materials_volume": {"thicknessFactor": 0.6, "attenuationDistance": 0.3,
                                                               "attenuationColor": [0.9, 0.55, 0.15]}}
    camera_at, sun_from = [1.6, 1.5, 3.4], [-3.0, 2.2, -0.2]
    tree["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.72, "aspectRatio": 1.0, "znear": 0.05}}]
    tree["extensions"] = {"KHR_lights_punctual": {"lights": [
        {"type": "directional", "name": "sun", "color": [1.0, 0.93, 0.82], "intensity": 2400.0},
        {"type": "spot", "name": "plinth-spot", "intensity": 4000.0, "spot": {"innerConeAngle": 0.25,
                                                                              "outerConeAngle": 0.45}},
        {"type": "point", "name": "fill", "color": [0.8, 0.85, 1.0], "intensity": 3000.0}]}}
    tree["extensionsUsed"] = sorted(set(tree.get("extensionsUsed", [])) | {
        "KHR_lights_punctual", "KHR_materials_transmission", "KHR_materials_volume"})
    first = len(tree["nodes"])
    tree["nodes"] += [
        {"name": "camera", "camera": 0, "translation": camera_at, "rotation": look_rotation(camera_at, [0.0, 0.6, -0.5])},
        {"name": "sun", "extensions": {"KHR_lights_punctual": {"light": 0}},
         "rotation": look_rotation(sun_from, [0.0, 0.0, -0.4])},
        {"name": "plinth-spot", "extensions": {"KHR_lights_punctual": {"light": 1}}, "translation": [0.5, 2.9, -0.6],
         "rotation": look_rotation([0.5, 2.9, -0.6], [0.5, 0.0, -0.599])},
        {"name": "fill", "extensions": {"KHR_lights_punctual": {"light": 2}}, "translation": [1.5, 2.4, 2.0]}]
    tree["scenes"][tree.get("scene", 0)]["nodes"] += list(range(first, first + 4))
    text = json.dumps(tree, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<I4s", len(text), b"JSON") + text + data[20 + length:]
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


if __name__ == "__main__":
    OUT.write_bytes(build())
    print(f"wrote {OUT} ({OUT.stat().st_size} bytes)")
