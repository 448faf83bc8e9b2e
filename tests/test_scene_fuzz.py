"""Fuzzing scene files: a valid scene with random JSON values put into random fields (at any depth)
either loads or stops with our one-line error naming the file; never another exception, a numpy
warning, or a loaded scene whose geometry holds NaN/Inf."""

import copy
import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image

from wgpu_rt.accel.geometry import GeometryBuffers, InstancedGeometry
from wgpu_rt.errors import WgpuRtError
from wgpu_rt.scene import load_scene

# Every kind of field: camera keyframes, all material kinds, each transform form, a mesh file, a texture
# that cuts its surface out, mesh keyframes, instances (still, in their own material, animated), every light type,
# light keyframes.
VALID = {
    "name": "fuzz",
    "frame_count": 3,
    "camera": {"origin": [0, 0.2, 3.9], "target": [0, 0, 0], "up": [0, 1, 0], "fov": 40, "fov_axis": "x",
               "keyframes": [{"frame": 0, "origin": [-0.3, 0.2, 3.9]}, {"frame": 2, "fov": 35}]},
    "materials": {
        "white": {"kind": "diffuse", "reflectance": [0.8, 0.7, 0.6]},
        "lamp": {"reflectance": 0.5, "emission": [12, 11, 9]},
        "copper": {"kind": "conductor", "roughness": 0.15, "eta": [0.27, 0.68, 1.32], "k": [3.61, 2.63, 2.29]},
        "glass": {"kind": "dielectric", "ior": 1.5, "roughness": 0.1, "transmittance": [0.5, 0.8, 0.6]},
        "coat": {"kind": "plastic", "ior": 1.4, "roughness": 0.3},
    },
    "meshes": [
        {"name": "floor", "shape": "rectangle", "material": "white",
         "transform": {"translate": [0, -1, 0], "rotate": {"axis": [1, 0, 0], "angle": -90}, "scale": 2}},
        {"name": "lamp", "shape": "rectangle", "material": "lamp",
         "transform": {"matrix": [[0.3, 0, 0, 0], [0, 0, -0.3, 0.99], [0, 0.3, 0, 0], [0, 0, 0, 1]]}},
        {"name": "tri", "file": "tri.obj", "material": "copper",
         "transform": {"rotate": [{"axis": [0, 1, 0], "angle": 30}], "scale": [0.3, 0.4, 0.5]}},
        {"name": "box", "shape": "cube", "material": "glass",
         "keyframes": [{"frame": 0, "translate": [0.4, -0.7, 0.2], "scale": 0.3},
                       {"frame": 2, "translate": [0.4, -0.4, 0.2], "scale": 0.3}]},
        {"name": "leaves", "shape": "rectangle", "material": "coat", "texture": "leaves.png", "alpha_cutoff": 0.4,
         "texture_repeat": 2, "transform": {"translate": [-0.5, 0, -0.5], "scale": 0.3}},
        {"name": "pebble", "file": "tri.obj", "material": "white", "transform": {"scale": 0.1},
         "instances": [{"transform": {"translate": [-0.5, -0.9, 0.3]}},
                       {"name": "red", "material": "copper", "transform": {"rotate": {"axis": [0, 0, 1], "angle": 45}}},
                       {"keyframes": [{"frame": 0, "scale": 2}, {"frame": 2, "translate": [0.1, 0, 0]}]}]},
    ],
    "lights": [{"type": "point", "position": [0.5, 0.6, 1.0], "intensity": [2, 2, 2]},
               {"type": "directional", "direction": [-0.3, -1, -0.2], "irradiance": 0.5,
                "keyframes": [{"frame": 1}, {"frame": 2, "direction": [0.3, -1, 0], "irradiance": [1, 0.5, 0]}]},
               {"type": "spot", "position": [0, 0.9, 0], "target": [0, -1, 0], "intensity": 3, "cutoff_angle": 30,
                "keyframes": [{"frame": 0, "beam_width": 10},
                              {"frame": 2, "position": [0.3, 0.9, 0], "target": [0, -1, 0.2], "intensity": 0}]}],
    "background": [0.02, 0.03, 0.05],
}


def field_paths(value, path=()):
    """Every key/index path into ``value`` (the top level excluded)."""
    children = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for key, child in children:
        yield path + (key,)
        yield from field_paths(child, path + (key,))


PATHS = list(field_paths(VALID))

numbers = st.one_of(
    st.integers(), st.integers(min_value=-10 ** 400, max_value=10 ** 400),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([1e39, -1e39, 3.4e38, 1e-50, -1e-45, 0.0, -0.0, 1, -1, 2 ** 63]))
json_values = st.one_of(
    st.recursive(
        st.none() | st.booleans() | numbers | st.text(max_size=6),
        lambda children: st.lists(children, max_size=5) | st.dictionaries(st.text(max_size=6), children, max_size=4),
        max_leaves=12),
    # Well-shaped numbers get past the type checks to the range and float32 checks.
    numbers, st.lists(numbers, min_size=3, max_size=3), st.lists(st.lists(numbers, min_size=4, max_size=4),
                                                                 min_size=4, max_size=4))
# An edit: a path, and a new value there (or None in the second slot: delete the field).
edits = st.lists(st.tuples(st.sampled_from(PATHS), st.one_of(st.tuples(json_values), st.none())),
                 min_size=1, max_size=3)


def holds(container, key) -> bool:
    if isinstance(container, dict):
        return key in container
    return isinstance(container, list) and isinstance(key, int) and key < len(container)


def apply(data, path, replacement):
    """Put ``replacement`` (a 1-tuple; None deletes) at ``path``, unless an earlier edit removed it."""
    parent = data
    for key in path[:-1]:
        if not holds(parent, key):
            return
        parent = parent[key]
    if holds(parent, path[-1]):
        if replacement is None:
            del parent[path[-1]]
        else:
            parent[path[-1]] = replacement[0]


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fuzz")
    (folder / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    leaves = np.full((4, 4, 4), 200, np.uint8)
    leaves[..., 3] = np.arange(16).reshape(4, 4) * 17
    Image.fromarray(leaves, "RGBA").save(folder / "leaves.png")
    return folder


def test_the_unedited_scene_loads(folder):
    path = folder / "valid.json"
    path.write_text(json.dumps(VALID))
    scene = load_scene(path)
    assert len(scene.meshes) == 8 and len(scene.lights) == 3 and scene.frame_count == 3
    assert scene.has_moving_lights
    assert scene.shapes()[-1] == [5, 6, 7]
    assert scene.meshes[4].is_cut_out


@pytest.mark.filterwarnings("error::RuntimeWarning")     # a numpy overflow warning is a finding too
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(changes=edits)
def test_random_values_load_or_fail_with_one_line(folder, changes):
    data = copy.deepcopy(VALID)
    for path, replacement in changes:
        apply(data, path, replacement)
    scene_path = folder / "scene.json"
    scene_path.write_text(json.dumps(data))
    _loads_finite_or_fails_with_one_line(scene_path, range(4))


def _loads_finite_or_fails_with_one_line(path, frames) -> None:
    """The scene file at ``path`` loads, and at each of ``frames`` it has (its frame count) its camera and the
    geometry a render builds first are finite; or it stops with one line that starts with the file's path."""
    try:
        scene = load_scene(path)
    except WgpuRtError as err:
        message = str(err)
        assert message.startswith(f"{path}") and "\n" not in message, message
        return
    for frame in (f for f in frames if f < scene.frame_count):
        camera = scene.camera_at(frame)
        assert all(np.all(np.isfinite(v)) for v in (camera.origin, *camera.basis()))
        geometry = GeometryBuffers.build(scene, frame)     # what a render does first for every frame
        assert np.all(np.isfinite(geometry.shading_normals)) and np.all(np.isfinite(geometry.object_motion))
        if InstancedGeometry.suits(scene):                # what a render with instances or motion does
            levels = InstancedGeometry(scene, frame)
            top, motion, records = levels.frame_arrays(frame)
            assert all(np.all(np.isfinite(a)) for a in (levels.triangles, top["lo"], top["hi"], motion,
                                                         records["to_world"], records["normal_to_world"]))
    assert np.all(np.isfinite(scene.background)) and np.all(scene.background >= 0)
    for light in (light for frame in frames if frame < scene.frame_count for light in scene.lights_at(frame)):
        assert all(np.all(np.isfinite(np.asarray(v, np.float32))) for v in vars(light).values() if not isinstance(v, dict))


def _glb_tree(name: str) -> tuple[bytes, dict]:
    from pathlib import Path

    from wgpu_rt.scene.file_materials import gltf_json

    path = Path(__file__).resolve().parents[1] / "examples" / "meshes" / name
    return path.read_bytes(), gltf_json(path)


def _turntable_paths(tree: dict) -> list:
    """The paths into a glTF tree that its animation, camera and material reading walks: its animations, their
    accessors and buffer views, the nodes they move, its cameras and its materials."""
    animated = {channel["target"]["node"] for a in tree["animations"] for channel in a["channels"]}
    used = {i for a in tree["animations"] for s in a["samplers"] for i in (s["input"], s["output"])}
    views = {tree["accessors"][i]["bufferView"] for i in used}
    return ([("animations",) + p for p in field_paths(tree["animations"])]
            + [("accessors", i) + p for i in used for p in field_paths(tree["accessors"][i])]
            + [("bufferViews", i) + p for i in views for p in field_paths(tree["bufferViews"][i])]
            + [("nodes", i) + p for i in animated for p in field_paths(tree["nodes"][i])]
            + [(key,) + p for key in ("cameras", "materials") for p in field_paths(tree[key])])


def _gallery_paths(tree: dict) -> list:
    """The paths that its lights, node hierarchy and materials are read from."""
    return [(key,) + p for key in ("extensions", "nodes", "materials", "scenes") for p in field_paths(tree[key])]


def _swaying_paths(tree: dict) -> list:
    """The paths that bend its meshes: its skins, meshes (attributes, morph targets, weights), the accessors and
    buffer views these name, and its animations."""
    used = {tree["skins"][s]["inverseBindMatrices"] for s in range(len(tree["skins"]))}
    used |= {a for mesh in tree["meshes"] for p in mesh["primitives"] for key, a in p["attributes"].items()
             if key.startswith(("JOINTS", "WEIGHTS"))}
    used |= {a for mesh in tree["meshes"] for p in mesh["primitives"] for t in p.get("targets", []) for a in t.values()}
    views = {tree["accessors"][i]["bufferView"] for i in used}
    return ([(key,) + p for key in ("skins", "meshes", "animations") for p in field_paths(tree[key])]
            + [("accessors", i) + p for i in used for p in field_paths(tree["accessors"][i])]
            + [("bufferViews", i) + p for i in views for p in field_paths(tree["bufferViews"][i])])


def _with_a_moving_lamp(name: str) -> tuple[bytes, dict]:
    """The turntable with its fill light moved by the camera's dolly sampler too (an animated light)."""
    from gltf_files import edit_glb_json

    data, tree = _glb_tree(name)

    def edit(tree):
        fill = next(i for i, node in enumerate(tree["nodes"]) if node.get("name") == "fill")
        tree["animations"][0]["channels"].append({"sampler": 1, "target": {"node": fill, "path": "translation"}})
        return tree
    edited = edit_glb_json(data, edit)
    return edited, edit(tree)


GLTF_FILES = {name: (data, paths(tree)) for name, paths, read in (
    ("turntable.glb", _turntable_paths, _with_a_moving_lamp), ("gallery.glb", _gallery_paths, _glb_tree),
    ("swaying.glb", _swaying_paths, _glb_tree)) for data, tree in [read(name)]}


@pytest.mark.filterwarnings("error::RuntimeWarning")
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(name=st.sampled_from(sorted(GLTF_FILES)), data=st.data())
def test_random_values_in_a_gltf_file_load_or_fail_with_one_line(tmp_path_factory, name, data):
    """The example glTF files with random values in the fields their scenes are read from (the turntable's, its
    fill light animated too: animations, accessors, buffer views, animated nodes, cameras and materials; the
    gallery's lights, nodes, materials and scene roots; what bends swaying's meshes): the file loads with a finite
    camera, lights and geometry at frames through its animation, or stops with one line naming it."""
    from gltf_files import edit_glb_json

    glb, paths = GLTF_FILES[name]
    changes = data.draw(st.lists(st.tuples(st.sampled_from(paths), st.one_of(st.tuples(json_values), st.none())),
                                 min_size=1, max_size=3))

    def edit(tree):
        for path, replacement in changes:
            apply(tree, path, replacement)
    path = tmp_path_factory.mktemp("gltf") / name
    path.write_bytes(edit_glb_json(glb, edit))
    _loads_finite_or_fails_with_one_line(path, range(0, 49, 16))
