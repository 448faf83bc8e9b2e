"""Scene layer: built-in scenes (cornell against Mitsuba 3), scene files, mesh files, errors,
GeometryBuffers, and the Mitsuba converter."""

import json
import re
import sys
import types
from pathlib import Path

import numpy as np
import pytest
import trimesh

from wgpu_rt.accel.geometry import GeometryBuffers, scene_material_names
from wgpu_rt.errors import DeviceLimitError, SceneError
from wgpu_rt.gpu import GpuContext
from wgpu_rt.scene import BUILTIN_SCENES, Camera, Scene, load_scene
from wgpu_rt.scene.transforms import compose, rotate, scale, transform_points, translate

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("*.json")) + sorted((ROOT / "examples").glob("*.toml"))


def canonical_triangles(triangles, decimals=5):
    """Triangles as a sorted list, each rotated to start at its smallest vertex (winding kept)."""
    out = []
    for tri in np.round(np.asarray(triangles, np.float64), decimals) + 0.0:
        start = min(range(3), key=lambda i: tuple(tri[i]))
        out.append(tuple(map(tuple, np.roll(tri, -start, axis=0))))
    return sorted(out)


def world_triangles(scene, frame=0):
    return {m.name: transform_points(m.transform_at(frame), m.vertices)[m.faces.astype(np.int64)]
            for m in scene.meshes}


# -- built-in scenes ----------------------------------------------------------------------------------
@pytest.mark.parametrize("name", [n for n in BUILTIN_SCENES if n != "mesh"])
def test_builtin_scenes_build(name):
    scene = load_scene(name)
    geometry = GeometryBuffers.build(scene, frame=scene.frame_count - 1)
    assert geometry.triangle_count > 0 and np.all(np.isfinite(geometry.triangles))
    assert np.allclose(np.linalg.norm(geometry.shading_normals, axis=2), 1, atol=1e-5)
    assert any(m.is_emissive for m in scene.materials.values()) or scene.lights


def test_moving_scene_moves():
    scene = load_scene("moving")
    assert scene.frame_count >= 16 and scene.has_motion
    first, last = scene.camera_at(0), scene.camera_at(scene.frame_count - 1)
    assert not np.allclose(first.origin, last.origin)
    moving = GeometryBuffers.build(scene, frame=5)
    assert not np.allclose(moving.object_motion, np.eye(4)), "some object must move between frames"
    assert np.allclose(GeometryBuffers.build(scene, frame=0).object_motion, np.eye(4))


def test_sun_room_dynamic_range():
    scene = load_scene("sun-room")
    emission = max(float(m.emission.max()) for m in scene.materials.values())
    assert emission >= 1e4


def test_mesh_scene_needs_and_fits_a_mesh(tmp_path):
    with pytest.raises(SceneError, match="needs a mesh file"):
        load_scene("mesh")
    path = tmp_path / "big.obj"
    trimesh.creation.box(extents=(50, 20, 10)).export(path)
    scene = load_scene("mesh", mesh=path)
    world = world_triangles(scene)["big"].reshape(-1, 3)
    assert np.isclose(world[:, 1].min(), -1, atol=1e-5), "the mesh stands on the floor"
    assert np.ptp(world, axis=0).max() <= 1.2 + 1e-5


def test_mesh_is_refused_for_scenes_that_take_none(tmp_path):
    path = tmp_path / "box.obj"
    trimesh.creation.box().export(path)
    with pytest.raises(SceneError, match=f"^cornell: takes no mesh file .*--mesh {path}"):
        load_scene("cornell", mesh=path)
    with pytest.raises(SceneError, match="scene.json: takes no mesh file"):
        load_scene(write_json(tmp_path, MINIMAL), mesh=path)
    with pytest.raises(SceneError, match="a Scene object: takes no mesh file"):
        load_scene(load_scene("cornell"), mesh=path)


def test_far_camera_has_a_finite_basis():
    """float32 squared norms overflow beyond 1e19 and vanish below 1e-19; the basis must not."""
    for distance in (1e20, 1e-30):
        assert np.all(np.isfinite(Camera([0, 0, distance], [0, 0, 0]).basis()))


def test_load_scene_dispatch(tmp_path):
    scene = load_scene("cornell")
    assert load_scene(scene) is scene
    with pytest.raises(SceneError, match="neither a built-in scene"):
        load_scene("no-such-scene")
    with pytest.raises(SceneError, match="missing.json: scene file not found"):
        load_scene(tmp_path / "missing.json")
    trimesh.creation.box().export(tmp_path / "box.ply")      # a mesh file: the 'mesh' scene around it
    assert [m.name for m in load_scene(tmp_path / "box.ply").meshes] == [
        m.name for m in load_scene("mesh", mesh=tmp_path / "box.ply").meshes]
    with pytest.raises(SceneError, match="gone.glb: mesh file not found"):
        load_scene(tmp_path / "gone.glb")


# -- cornell against Mitsuba 3 (fixture mi: conftest.py) ---------------------------------------------
def test_the_cross_check_uses_a_mitsuba_variant_that_loads():
    """The lent GPUs' Mitsuba lists scalar_rgb among its variants but ships only the CUDA and LLVM ones:
    the cross-check takes the next variant that loads, keeps one already set, and says None where none does."""
    class FakeMitsuba:
        def __init__(self, loadable):
            self.loadable, self.current = loadable, None

        def variants(self):
            return ["scalar_rgb", "llvm_ad_rgb", "cuda_ad_rgb"]

        def variant(self):
            return self.current

        def set_variant(self, name):
            if name not in self.loadable:
                raise ModuleNotFoundError(f"No module named 'mitsuba.{name}'")
            self.current = name

    from wgpu_rt.scene.mitsuba import use_variant

    trimmed = FakeMitsuba({"cuda_ad_rgb", "llvm_ad_rgb"})
    assert use_variant(trimmed) == "cuda_ad_rgb" == trimmed.variant()
    trimmed.current = "llvm_ad_rgb"
    assert use_variant(trimmed) == "llvm_ad_rgb"
    assert use_variant(FakeMitsuba(set())) is None
    assert use_variant(FakeMitsuba({"scalar_rgb", "cuda_ad_rgb"})) == "scalar_rgb"


def test_cornell_equals_mitsuba(mi):
    reference = mi.load_dict(mi.cornell_box())
    ours = load_scene("cornell")
    theirs = {}
    for shape in reference.shapes():
        vertices = np.array(shape.vertex_positions_buffer()).reshape(-1, 3)
        faces = np.array(shape.faces_buffer()).reshape(-1, 3)
        theirs[shape.id()] = (vertices[faces], shape)
    ours_world = world_triangles(ours)
    # Mitsuba merges shapes that share a BSDF; compare per BSDF colour and emitter.
    all_theirs = canonical_triangles(np.concatenate([t for t, _ in theirs.values()]))
    all_ours = canonical_triangles(np.concatenate(list(ours_world.values())))
    assert all_theirs == all_ours
    light_theirs = next(t for t, s in theirs.values() if s.emitter() is not None)
    assert canonical_triangles(light_theirs) == canonical_triangles(ours_world["light"])
    params = mi.traverse(reference)
    radiance = next(np.array(params[k]) for k in params.keys() if k.endswith("emitter.radiance.value"))
    np.testing.assert_allclose(ours.materials["light"].emission, radiance.ravel(), rtol=1e-6)
    reflectances = sorted(tuple(np.round(np.array(params[k], np.float64).ravel(), 6)) for k in params.keys()
                          if k.endswith("reflectance.value"))
    ours_reflectances = sorted({tuple(np.round(m.reflectance.astype(np.float64), 6))
                                for m in ours.materials.values()})
    assert sorted(set(reflectances)) == ours_reflectances
    sensor = mi.cornell_box()["sensor"]
    to_world = np.array(sensor["to_world"].matrix)
    camera = ours.camera
    np.testing.assert_allclose(to_world[:3, 3], camera.origin, atol=1e-6)
    right, up, forward = camera.basis()
    np.testing.assert_allclose(to_world[:3, 2], forward, atol=1e-6)
    np.testing.assert_allclose(to_world[:3, 1], up, atol=1e-6)
    assert camera.fov == sensor["fov"] and camera.fov_axis == sensor["fov_axis"]


def test_to_mitsuba_cornell_renders_like_mitsubas_own(mi):
    from wgpu_rt.scene.mitsuba import to_mitsuba

    size, spp = 16, 1024

    def reference(seed):
        scene = mi.cornell_box()
        scene["sensor"]["film"].update(width=size, height=size, rfilter={"type": "box"})
        scene["sensor"]["sampler"].update(sample_count=spp, seed=seed)
        return np.array(mi.render(mi.load_dict(scene)))

    converted = to_mitsuba(load_scene("cornell"), size, size, spp, max_depth=8, seed=1)
    ours = np.array(mi.render(mi.load_dict(converted)))
    first, second = reference(1), reference(2)
    noise = np.abs(first - second).mean()
    assert np.abs(ours - first).mean() < 1.5 * noise
    np.testing.assert_allclose(ours.mean(axis=(0, 1)), first.mean(axis=(0, 1)), rtol=0.02)


@pytest.mark.parametrize("spec", ["cornell-glossy", "sun-room", "moving", *map(str, EXAMPLES)])
def test_to_mitsuba_converts_every_feature(mi, spec):
    from wgpu_rt.scene.mitsuba import to_mitsuba

    scene = load_scene(spec)
    converted = to_mitsuba(scene, 8, 6, 2, max_depth=5, frame=scene.frame_count - 1, seed=3)
    # volpath passes a mask's holes (a cut-out surface) as the tracer does and has media (absorbing glass); path
    # otherwise
    integrator = "volpath" if any(mesh.is_cut_out or scene.materials[mesh.material].absorbs
                                  for mesh in scene.meshes) else "path"
    assert converted["integrator"] == {"type": integrator, "max_depth": 5}
    assert converted["sensor"]["film"]["rfilter"] == {"type": "box"}
    image = np.array(mi.render(mi.load_dict(converted)))
    assert image.shape == (6, 8, 3) and np.all(np.isfinite(image)) and image.max() > 0
    loaded = mi.load_dict(converted)
    assert len(loaded.emitters()) >= len(scene.lights) + sum(
        scene.materials[m.material].is_emissive for m in scene.meshes)


def test_to_mitsuba_material_mapping():
    from wgpu_rt.scene.mitsuba import material_to_bsdf
    from wgpu_rt.scene.model import Material

    assert material_to_bsdf(Material("conductor", roughness=0.3))["type"] == "roughconductor"
    assert material_to_bsdf(Material("conductor", roughness=0.3))["distribution"] == "ggx"
    assert material_to_bsdf(Material("conductor"))["type"] == "conductor"
    assert material_to_bsdf(Material("dielectric", ior=1.33))["int_ior"] == pytest.approx(1.33)
    assert material_to_bsdf(Material("dielectric", roughness=0.1))["type"] == "roughdielectric"
    assert material_to_bsdf(Material("dielectric", transmittance=[0.2, 0.5, 1]))["specular_transmittance"] == {
        "type": "rgb", "value": pytest.approx([0.2, 0.5, 1])}
    assert material_to_bsdf(Material("plastic", roughness=0.2))["type"] == "roughplastic"
    assert material_to_bsdf(Material("plastic"))["type"] == "plastic"


# -- scene files -------------------------------------------------------------------------------------
@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_examples_load(path):
    scene = load_scene(path)
    assert isinstance(scene, Scene) and scene.meshes
    GeometryBuffers.build(scene, frame=scene.frame_count - 1)


def test_showroom_example_features():
    scene = load_scene(ROOT / "examples" / "showroom.json")
    assert scene.frame_count == 8 and scene.has_motion and len(scene.lights) == 2
    pyramid = next(m for m in scene.meshes if m.name == "pyramid")
    assert pyramid.normals is not None, "the OBJ's vertex normals are kept"
    ball = next(m for m in scene.meshes if m.name == "ball")
    np.testing.assert_allclose(ball.transform_at(7)[:3, 3], [0.45, -0.4, 0.2], atol=1e-6)
    np.testing.assert_allclose(scene.camera_at(7).origin, [0.3, 0.2, 3.9], atol=1e-6)
    np.testing.assert_allclose(scene.camera_at(7).target, [0, -0.2, 0], atol=1e-6)


MINIMAL = {
    "camera": {"origin": [0, 0, 3], "target": [0, 0, 0]},
    "materials": {"white": {"reflectance": 0.8}, "lamp": {"emission": [5, 5, 5]}},
    "meshes": [{"shape": "cube", "material": "white"},
               {"shape": "rectangle", "material": "lamp", "transform": {"translate": [0, 2, 0]}},
               {"shape": "sphere", "material": "white"}],
}


def write_json(tmp_path, data, name="scene.json"):
    path = tmp_path / name
    path.write_text(json.dumps(data))
    return path


def test_json_and_toml_agree(tmp_path):
    toml = """
[camera]
origin = [0, 0, 3]
target = [0, 0, 0]
[materials.white]
reflectance = 0.8
[materials.lamp]
emission = [5, 5, 5]
[[meshes]]
shape = "cube"
material = "white"
[[meshes]]
shape = "rectangle"
material = "lamp"
transform = { translate = [0, 2, 0] }
[[meshes]]
shape = "sphere"
material = "white"
"""
    (tmp_path / "scene.toml").write_text(toml)
    a, b = load_scene(write_json(tmp_path, MINIMAL)), load_scene(tmp_path / "scene.toml")
    assert [m.name for m in a.meshes] == [m.name for m in b.meshes]
    for x, y in zip(a.meshes, b.meshes):
        np.testing.assert_array_equal(x.transform, y.transform)
    assert a.materials.keys() == b.materials.keys()


def test_transform_order_and_matrix(tmp_path):
    data = json.loads(json.dumps(MINIMAL))
    data["meshes"][0]["transform"] = {"translate": [1, 2, 3], "rotate": {"axis": [0, 0, 1], "angle": 90},
                                      "scale": [2, 1, 1]}
    scene = load_scene(write_json(tmp_path, data))
    # scale first: (1,0,0) → (2,0,0); then rotate 90° about z → (0,2,0); then translate.
    np.testing.assert_allclose(transform_points(scene.meshes[0].transform, [[1, 0, 0]]), [[1, 4, 3]], atol=1e-6)
    matrix = np.array(scene.meshes[0].transform, float).tolist()
    data["meshes"][0]["transform"] = {"matrix": matrix}
    np.testing.assert_allclose(load_scene(write_json(tmp_path, data)).meshes[0].transform, matrix, atol=1e-7)


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["meshes"].append({"shape": "cube", "material": "gold"}),
     "scene.json: meshes[3].material: unknown material 'gold'"),
    (lambda d: d["camera"].update(fov="wide"), "scene.json: camera.fov: expected a number, got 'wide'"),
    (lambda d: d.update(colour=[1, 2, 3]), "scene.json: (top level): unknown key 'colour'"),
    (lambda d: d["materials"]["white"].update(shine=1), "scene.json: materials.white: unknown key 'shine'"),
    (lambda d: d["materials"]["white"].update(kind="velvet"), "scene.json: materials.white.kind: expected one of"),
    (lambda d: d["materials"]["white"].update(roughness=3), "scene.json: materials.white: roughness must be in"),
    (lambda d: d["meshes"][0].update(transform={"matrix": [[1, 0], [0, 1]]}),
     "scene.json: meshes[0].transform.matrix: expected a 4×4"),
    (lambda d: d["meshes"][0].update(transform={"translate": [1, 2]}),
     "scene.json: meshes[0].transform.translate: expected a list of 3 numbers"),
    (lambda d: d["meshes"][0].update(transform={"rotate": {"axis": [0, 1, 0]}}),
     r"scene.json: meshes\[0\].transform.rotate\[0\].angle: required field is missing"),
    (lambda d: d["meshes"][1].update(file="x.obj"), r"scene.json: meshes\[1\]: give exactly one of 'file'"),
    (lambda d: d["meshes"][2].update(shape="torus"), r"scene.json: meshes\[2\].shape: expected one of"),
    (lambda d: d["meshes"][0].update(keyframes=[{"frame": -1}]), r"meshes\[0\].keyframes\[0\].frame: frames are"),
    (lambda d: d["camera"].update(keyframes=[{"frame": 2, "origni": [0, 0, 1]}]),
     r"camera.keyframes\[0\]: unknown key 'origni'"),
    (lambda d: d.pop("camera"), "scene.json: camera: required field is missing"),
    (lambda d: d["camera"].update(up=[0, 0, 1]), "scene.json: camera.up: up must not be parallel"),
    (lambda d: d.update(lights=[{"type": "area"}]), r"scene.json: lights\[0\].type: expected one of"),
    (lambda d: d.update(lights=[{"type": "point", "position": [0, 0, 0], "intensity": True}]),
     r"scene.json: lights\[0\].intensity: expected a number or a list of 3 numbers"),
    (lambda d: d.update(meshes="cube"), "scene.json: meshes: expected a list"),
    (lambda d: d.update(frame_count=0), "scene.json: frame_count: expected at least 1 frame"),
    # Values of the wrong kind: null tables, integers too large for any float, nesting for a number.
    (lambda d: d.update(camera=None), "scene.json: camera: expected a table/object, got None"),
    (lambda d: d.update(materials=None), "scene.json: materials: expected a table/object, got None"),
    (lambda d: d["meshes"][1].update(transform=None),
     "scene.json: meshes[1].transform: expected a table/object, got None"),
    (lambda d: d["camera"].update(fov=10 ** 400), "scene.json: camera.fov: expected finite numbers within float32"),
    (lambda d: d["meshes"][1]["transform"].update(translate=[10 ** 400, 0, 0]),
     "scene.json: meshes[1].transform.translate: expected finite numbers within float32"),
    (lambda d: d["camera"].update(fov=[[[[[40]]]]]), "scene.json: camera.fov: expected a number, got [[[[[40]]]]]"),
    # Finite in float64 but Inf once cast to float32, which is what the GPU gets.
    (lambda d: d.update(lights=[{"type": "point", "position": [0, 1, 0], "intensity": 1e39}]),
     "scene.json: lights[0].intensity: expected finite numbers within float32 range"),
    (lambda d: d.update(background=1e39), "scene.json: background: expected finite numbers within float32 range"),
    (lambda d: d["camera"].update(origin=[1e39, 0, 0]), "scene.json: camera.origin: expected finite numbers"),
    (lambda d: d["camera"].update(fov=1e-50), "scene.json: camera: fov must be in [0.001, 180) degrees"),
    # Composed transforms, each keyframe included, must stay invertible and within float32.
    (lambda d: d["meshes"][0].update(transform={"scale": 1e-50}),
     "scene.json: meshes[0].transform: the transform of mesh 'cube' is singular in float32"),
    (lambda d: d["meshes"][0].update(keyframes=[{"frame": 0}, {"frame": 4, "scale": 3e38, "translate": [3e38, 0, 0]}]),
     "scene.json: meshes[0].keyframes[1]: the transform of mesh 'cube' puts vertices beyond ±1e+09"),
    (lambda d: d["meshes"][0].update(keyframes=[{"frame": 0, "scale": 1}, {"frame": 2, "scale": -1}]),
     "scene.json: meshes[0].keyframes: the transform of mesh 'cube' blends to a singular one at frame 1"),
    (lambda d: d["camera"].update(keyframes=[{"frame": 1, "target": [0, 0, -1e19]}]),
     "scene.json: camera.keyframes[0].target: positions must lie within ±1e+09"),
    (lambda d: d["meshes"][0].update(transform={"matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]}),
     "scene.json: meshes[0].transform.matrix: the last row must be [0, 0, 0, 1]"),
    # Physically impossible values: negative light, energy-creating or negative surfaces.
    (lambda d: d.update(lights=[{"type": "point", "position": [0, 1, 0], "intensity": [1, -1, 1]}]),
     "scene.json: lights[0].intensity: must not be negative"),
    (lambda d: d.update(lights=[{"type": "directional", "direction": [0, -1, 0], "irradiance": -2}]),
     "scene.json: lights[0].irradiance: must not be negative"),
    (lambda d: d["materials"]["white"].update(reflectance=5),
     "scene.json: materials.white: reflectance must be in [0, 1] per channel, got [5.0, 5.0, 5.0]"),
    (lambda d: d["materials"]["white"].update(reflectance=[0.5, 0.5, -0.1]),
     "scene.json: materials.white: reflectance must be in [0, 1] per channel"),
    (lambda d: d["materials"]["lamp"].update(emission=-1),
     "scene.json: materials.lamp: emission must be non-negative"),
    (lambda d: d["materials"]["white"].update(kind="conductor", k=[-1, 2, 3]),
     "scene.json: materials.white: k must be non-negative"),
    (lambda d: d["materials"]["white"].update(kind="dielectric", ior=0),
     "scene.json: materials.white: ior must be positive"),
])
@pytest.mark.filterwarnings("error::RuntimeWarning")    # no numpy overflow warnings on the way to the error
def test_scene_file_errors_name_file_and_field(tmp_path, edit, message):
    data = json.loads(json.dumps(MINIMAL))
    edit(data)
    with pytest.raises(SceneError, match=message if "\\" in message else re.escape(message)):
        load_scene(write_json(tmp_path, data))


def test_exact_error_message_for_unknown_material(tmp_path):
    data = json.loads(json.dumps(MINIMAL))
    data["meshes"][2]["material"] = "gold"
    path = write_json(tmp_path, data)
    with pytest.raises(SceneError) as caught:
        load_scene(path)
    assert str(caught.value) == f"{path}: meshes[2].material: unknown material 'gold'"


# -- instances ----------------------------------------------------------------------------------------
INSTANCED = {
    "camera": {"origin": [0, 0, 3], "target": [0, 0, 0]},
    "materials": {"white": {"reflectance": 0.8}, "red": {"reflectance": [0.8, 0.1, 0.1]}},
    "meshes": [{"shape": "rectangle", "material": "white", "name": "floor"},
               {"name": "box", "shape": "cube", "material": "white", "transform": {"scale": 0.2},
                "instances": [{"transform": {"translate": [1, 0, 0]}},
                              {"name": "red box", "material": "red",
                               "transform": {"translate": [-1, 0, 0], "rotate": {"axis": [0, 0, 1], "angle": 90}}},
                              {"keyframes": [{"frame": 0}, {"frame": 3, "translate": [0, 1, 0]}]}]}],
}

INSTANCED_TOML = """
[camera]
origin = [0, 0, 3]
target = [0, 0, 0]
[materials.white]
reflectance = 0.8
[materials.red]
reflectance = [0.8, 0.1, 0.1]
[[meshes]]
shape = "rectangle"
material = "white"
name = "floor"
[[meshes]]
name = "box"
shape = "cube"
material = "white"
transform = { scale = 0.2 }
[[meshes.instances]]
transform = { translate = [1, 0, 0] }
[[meshes.instances]]
name = "red box"
material = "red"
transform = { translate = [-1, 0, 0], rotate = { axis = [0, 0, 1], angle = 90 } }
[[meshes.instances]]
keyframes = [{ frame = 0 }, { frame = 3, translate = [0, 1, 0] }]
"""


def test_instances_place_one_shape_many_times(tmp_path):
    """A mesh entry's instances are meshes sharing one set of arrays, named box[i] unless named, in the
    entry's material unless given one, each placed by its own transform (or keyframes) after the
    entry's: the same scene from JSON and TOML."""
    (tmp_path / "scene.toml").write_text(INSTANCED_TOML)
    for scene in (load_scene(write_json(tmp_path, INSTANCED)), load_scene(tmp_path / "scene.toml")):
        boxes = scene.meshes[1:]
        assert [m.name for m in boxes] == ["box[0]", "red box", "box[2]"]
        assert [m.material for m in boxes] == ["white", "red", "white"]
        assert scene.shapes() == [[0], [1, 2, 3]] and scene.has_instances and scene.frame_count == 4
        assert all(m.vertices is boxes[0].vertices and m.faces is boxes[0].faces for m in boxes)
        assert not boxes[0].vertices.flags.writeable, "an edit would move every instance"
        corner = [[1, 1, 1]]
        np.testing.assert_allclose(transform_points(boxes[0].transform, corner), [[1.2, 0.2, 0.2]], atol=1e-6)
        np.testing.assert_allclose(transform_points(boxes[1].transform, corner), [[-1.2, 0.2, 0.2]], atol=1e-6)
        np.testing.assert_allclose(transform_points(boxes[2].transform_at(3), corner), [[0.2, 1.2, 0.2]], atol=1e-6)
        assert not boxes[0].keyframes and boxes[2].is_animated


def test_mesh_keyframes_animate_every_instance(tmp_path):
    """The entry's own keyframes pose the shape for all its (still) instances: at every frame each
    instance is its placement after the entry's pose."""
    data = json.loads(json.dumps(INSTANCED))
    box = data["meshes"][1]
    box["keyframes"] = [{"frame": 0, "scale": 0.2}, {"frame": 4, "scale": 0.2, "translate": [0, 0, -1]}]
    box["instances"] = box["instances"][:2]
    scene = load_scene(write_json(tmp_path, data))
    for frame in (0, 2, 4):
        pose = np.array(scene.meshes[1].transform_at(frame), np.float64)
        red = np.array(scene.meshes[2].transform_at(frame), np.float64)
        np.testing.assert_allclose(pose[:3, 3], [1, 0, -0.25 * frame], atol=1e-6)
        np.testing.assert_allclose(red[:3, 3], [-1, 0, -0.25 * frame], atol=1e-6)
    assert scene.frame_count == 5


def test_instances_of_a_multi_geometry_file(tmp_path):
    """Each placed geometry of a mesh file is placed once per instance: parts × instances meshes, two
    shapes, named after the instance and the node."""
    group = trimesh.Scene()
    group.add_geometry(trimesh.creation.box(), node_name="low")
    group.add_geometry(trimesh.creation.icosphere(subdivisions=1), node_name="high")
    group.export(tmp_path / "group.glb")
    data = json.loads(json.dumps(INSTANCED))
    data["meshes"][1] = {"file": "group.glb", "material": "white",
                         "instances": [{"transform": {"translate": [i, 0, 0]}} for i in range(3)]}
    scene = load_scene(write_json(tmp_path, data))
    assert sorted(m.name for m in scene.meshes[1:]) == sorted(f"group[{i}]/{node}" for i in range(3)
                                                              for node in ("low", "high"))
    assert sorted(map(len, scene.shapes())) == [1, 3, 3]


@pytest.mark.parametrize("edit, message", [
    (lambda box: box.update(instances="many"), "meshes[1].instances: expected a list, got 'many'"),
    (lambda box: box.update(instances=[]),
     "meshes[1].instances: expected at least one instance (leave 'instances' out to place the mesh once)"),
    (lambda box: box["instances"].append(3), "meshes[1].instances[3]: expected a table/object, got 3"),
    (lambda box: box["instances"][1].update(material="gold"),
     "meshes[1].instances[1].material: unknown material 'gold'"),
    (lambda box: box["instances"][0].update(translate=[1, 2, 3]), "meshes[1].instances[0]: unknown key 'translate'"),
    (lambda box: box["instances"][0].update(name=5), "meshes[1].instances[0].name: expected a string, got 5"),
    (lambda box: box["instances"][2]["keyframes"][1].update(frame=-1),
     "meshes[1].instances[2].keyframes[1].frame: frames are numbered from 0, got -1"),
    (lambda box: box["instances"][1]["transform"].update(scale=1e-50),
     ("meshes[1].instances[1].transform: the transform of mesh 'red box' is singular in float32 (a zero or "
      "vanishing scale)")),
    (lambda box: box["instances"][0]["transform"].update(translate=[2e9, 0, 0]),
     ("meshes[1].instances[0].transform: the transform of mesh 'box[0]' puts vertices beyond ±1e+09 (the "
      "tracer's float32 range)")),
    (lambda box: box["instances"][2]["keyframes"][1].update(scale=[1e20, 1e20, 1e20]),
     ("meshes[1].instances[2].keyframes[1]: the transform of mesh 'box[2]' puts vertices beyond ±1e+09 (the "
      "tracer's float32 range)")),
    (lambda box: box["transform"].update(scale=0),
     "meshes[1].transform.scale: scale factors must be non-zero"),
    (lambda box: box["transform"].update(scale=1e-40),
     "meshes[1].transform: the transform of mesh 'box' is singular in float32 (a zero or vanishing scale)"),
    (lambda box: box.update(keyframes=[{"frame": 0}, {"frame": 1, "translate": [0, 1, 0]}]),
     "meshes[1].instances[2].keyframes: the mesh has keyframes too: animate either the mesh or its instances"),
    (lambda box: box.update(keyframes=[{"frame": 0, "scale": 1}, {"frame": 2, "scale": -1}],
                            instances=box["instances"][:1]),
     ("meshes[1].keyframes: the transform of mesh 'box[0]' blends to a singular one at frame 1, between "
      "keyframes 0 and 2: add keyframes")),
])
@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_instance_errors_are_one_exact_line(tmp_path, edit, message):
    data = json.loads(json.dumps(INSTANCED))
    edit(data["meshes"][1])
    path = write_json(tmp_path, data)
    with pytest.raises(SceneError) as caught:
        load_scene(path)
    assert str(caught.value) == f"{path}: {message}"


def test_unparsable_files(tmp_path):
    (tmp_path / "bad.json").write_text("{ not json")
    with pytest.raises(SceneError, match="bad.json: cannot parse"):
        load_scene(tmp_path / "bad.json")
    (tmp_path / "deep.json").write_text("[" * 100_000 + "]" * 100_000)      # RecursionError in json
    with pytest.raises(SceneError, match="deep.json: cannot parse"):
        load_scene(tmp_path / "deep.json")
    (tmp_path / "long.json").write_text('{"frame_count": 1' + "0" * 5000 + "}")  # over Python's int limit
    with pytest.raises(SceneError, match="long.json: cannot parse"):
        load_scene(tmp_path / "long.json")
    (tmp_path / "bad.toml").write_text("[camera\norigin = ")
    with pytest.raises(SceneError, match="bad.toml: cannot parse"):
        load_scene(tmp_path / "bad.toml")


# -- mesh files ---------------------------------------------------------------------------------------
def scene_with_mesh(tmp_path, file):
    data = json.loads(json.dumps(MINIMAL))
    data["meshes"][0] = {"file": file, "material": "white"}
    return write_json(tmp_path, data)


@pytest.mark.parametrize("content, message", [
    (None, "mesh file not found"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n", "face index out of range"),
    ("v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "NaN or infinite"),
    ("v 0 0 0\nv 1 0 0\n", "no triangles"),
])
def test_bad_mesh_files(tmp_path, content, message):
    name = "missing.obj" if content is None else "mesh.obj"
    if content is not None:
        (tmp_path / name).write_text(content)
    with pytest.raises(SceneError, match=f"scene.json: meshes\\[0\\].file: .*{name}.*{message}"):
        load_scene(scene_with_mesh(tmp_path, name))


def test_latin1_comment_obj_loads(tmp_path):
    (tmp_path / "mesh.obj").write_bytes(b"# caf\xe9 (Latin-1)\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    scene = load_scene(scene_with_mesh(tmp_path, "mesh.obj"))
    assert len(next(m for m in scene.meshes if m.name == "mesh").faces) == 1


def test_missing_text_decoder_is_named(tmp_path, monkeypatch):
    """Without charset_normalizer (now a dependency) trimesh cannot read non-UTF-8 text: say so."""
    monkeypatch.setitem(sys.modules, "charset_normalizer", None)
    (tmp_path / "mesh.obj").write_bytes(b"# caf\xe9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(SceneError, match="mesh.obj: cannot read mesh file: trimesh needs a Python package that "
                                         "is not installed: charset_normalizer$"):
        load_scene(scene_with_mesh(tmp_path, "mesh.obj"))


@pytest.mark.parametrize("name", ["garbage.obj", "garbage.stl"])
def test_garbage_text_mesh_files(tmp_path, name):
    (tmp_path / name).write_bytes(np.random.default_rng(1).bytes(4096))
    with pytest.raises(SceneError, match=f"meshes\\[0\\].file: .*{name}: ") as caught:
        load_scene(scene_with_mesh(tmp_path, name))
    assert "ModuleNotFoundError" not in str(caught.value)


def test_malformed_binary_mesh(tmp_path):
    (tmp_path / "mesh.glb").write_bytes(b"glTF\x02\x00\x00\x00garbage")
    with pytest.raises(SceneError, match="mesh.glb: cannot read the glTF file.s JSON"):
        load_scene(scene_with_mesh(tmp_path, "mesh.glb"))


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_placement_overflowing_through_a_node_transform(tmp_path):
    """The file's node transform (×1000) times the entry's (×1e36) leaves float32: named at load time."""
    group = trimesh.Scene()
    group.add_geometry(trimesh.creation.box(), node_name="box", transform=np.diag([1e3, 1e3, 1e3, 1]))
    group.export(tmp_path / "big.glb")
    data = json.loads(json.dumps(MINIMAL))
    data["meshes"][0] = {"file": "big.glb", "material": "white", "transform": {"scale": 1e36}}
    with pytest.raises(SceneError, match=r"scene.json: meshes\[0\].transform: the transform of mesh 'big' "
                                         r"overflows float32"):
        load_scene(write_json(tmp_path, data))


def test_ply_and_multi_geometry_glb(tmp_path):
    box = trimesh.creation.box(extents=(1, 1, 1))
    box.export(tmp_path / "box.ply")
    scene = load_scene(scene_with_mesh(tmp_path, "box.ply"))
    assert canonical_triangles(world_triangles(scene)["box"]) == canonical_triangles(box.vertices[box.faces])

    group = trimesh.Scene()
    lift = np.eye(4)
    lift[:3, 3] = [0, 5, 0]
    group.add_geometry(box, node_name="low")
    group.add_geometry(trimesh.creation.icosphere(subdivisions=1), node_name="high", transform=lift)
    group.export(tmp_path / "group.glb", include_normals=True)
    scene = load_scene(scene_with_mesh(tmp_path, "group.glb"))
    parts = [m for m in scene.meshes if m.name.startswith("group/")]
    assert len(parts) == 2
    reference = group.to_mesh() if hasattr(group, "to_mesh") else group.dump(concatenate=True)
    ours = np.concatenate([world_triangles(scene)[m.name] for m in parts])
    assert canonical_triangles(ours, 4) == canonical_triangles(reference.vertices[reference.faces], 4)
    sphere = next(m for m in parts if len(m.faces) != 12)
    assert sphere.normals is not None, "glTF vertex normals are kept"


def test_a_geometry_placed_at_several_nodes_is_instanced(tmp_path):
    """A glTF placing one geometry at three nodes loads as three placements of one shape (the same
    arrays, read once), each where its node puts it; an entry's instances of such a file still share
    them. Distinct geometries, even equal ones, stay shapes of their own."""
    placements = {"left": translate([-3, 0, 0]),
                  "turned": compose(translate([3, 1, 0]), rotate([0, 1, 1], 70)),
                  "small": compose(translate([0, 4, -2]), scale([0.5, 2, 1]))}
    box = trimesh.creation.box(extents=(1, 2, 3))
    group = trimesh.Scene()
    group.add_geometry(box, geom_name="box", node_name="left", transform=placements["left"])
    for node in ("turned", "small"):    # more nodes referencing the same geometry
        group.graph.update(frame_to=node, frame_from=group.graph.base_frame, geometry="box",
                           matrix=placements[node])
    assert len(group.geometry) == 1
    group.export(tmp_path / "boxes.glb")
    scene = load_scene(scene_with_mesh(tmp_path, "boxes.glb"))
    boxes = {m.name: m for m in scene.meshes if m.name.startswith("boxes/")}
    assert sorted(boxes) == sorted(f"boxes/{node}" for node in placements)
    first, *others = boxes.values()
    assert all(m.vertices is first.vertices and m.faces is first.faces for m in others)
    assert len({m.shape_key for m in boxes.values()}) == 1 and scene.has_instances
    world = world_triangles(scene)
    for node, matrix in placements.items():
        expanded = transform_points(matrix, box.vertices)[box.faces]
        assert canonical_triangles(world[f"boxes/{node}"], 4) == canonical_triangles(expanded, 4), node

    data = json.loads(json.dumps(MINIMAL))
    data["meshes"][0] = {"file": "boxes.glb", "material": "white",
                         "instances": [{"transform": {"translate": [0, 0, i]}} for i in range(2)]}
    scene = load_scene(write_json(tmp_path, data))
    placed = [m for m in scene.meshes if m.name.startswith("boxes[")]
    assert len(placed) == 6 and len({m.shape_key for m in placed}) == 1

    twins = trimesh.Scene()
    twins.add_geometry(trimesh.creation.box(), node_name="here")
    twins.add_geometry(trimesh.creation.box(), node_name="there", transform=translate([2, 0, 0]))
    twins.export(tmp_path / "twins.glb")
    scene = load_scene(scene_with_mesh(tmp_path, "twins.glb"))
    parts = [m for m in scene.meshes if m.name.startswith("twins/")]
    assert len(parts) == 2 and not np.shares_memory(parts[0].vertices, parts[1].vertices)
    assert len({m.shape_key for m in parts}) == 2 and all(m.vertices.flags.writeable for m in parts)


# -- geometry buffers ---------------------------------------------------------------------------------
def test_geometry_ids_and_order():
    scene = load_scene("cornell")
    geometry = GeometryBuffers.build(scene)
    names = scene_material_names(scene)
    assert names == list(scene.materials)
    # Every triangle keeps its own mesh's material and its world position.
    for object_id, mesh in enumerate(scene.meshes):
        ours = geometry.triangles[geometry.object_ids == object_id]
        assert canonical_triangles(ours) == canonical_triangles(world_triangles(scene)[mesh.name])
        assert set(geometry.material_ids[geometry.object_ids == object_id]) == {names.index(mesh.material)}
    # Triangles are in BVH leaf order.
    np.testing.assert_array_equal(geometry.triangles,
                                  np.concatenate(list(world_triangles(scene).values()))[geometry.bvh.order])
    nodes, positions, attributes, motion = geometry.packed_arrays()
    assert nodes.itemsize == 32 and positions.nbytes == 48 * geometry.triangle_count
    assert attributes.nbytes == 48 * geometry.triangle_count and motion.nbytes == 64 * len(scene.meshes)


def test_unknown_material_in_programmatic_scene():
    scene = load_scene("cornell")
    scene.meshes[3].material = "gold"
    with pytest.raises(SceneError, match="mesh 'back': unknown material 'gold'"):
        GeometryBuffers.build(scene)


def test_device_limit_names_the_buffer():
    fake = GpuContext(adapter=types.SimpleNamespace(summary="tiny test device"), device=None)
    geometry = GeometryBuffers.build(load_scene("cornell-glossy"))
    nodes_bytes = geometry.packed_arrays(orderings=1)[0].nbytes   # the largest array with one node copy
    fake.__dict__["limits"] = {"max-storage-buffer-binding-size": nodes_bytes - 1, "max-buffer-size": 1 << 30}
    with pytest.raises(DeviceLimitError, match="BVH nodes .*max-storage-buffer-binding-size.*tiny test"):
        geometry.upload(fake)


def test_node_orderings_fall_back_to_one_copy_when_eight_do_not_fit():
    fake = GpuContext(adapter=types.SimpleNamespace(summary="tiny test device"), device=None)
    geometry = GeometryBuffers.build(load_scene("cornell-glossy"))
    one_copy = geometry.packed_arrays(orderings=1)[0].nbytes
    fake.__dict__["limits"] = {"max-storage-buffer-binding-size": 8 * one_copy, "max-buffer-size": 1 << 30}
    assert geometry.orderings(fake) == 8
    fake.__dict__["limits"]["max-storage-buffer-binding-size"] = 8 * one_copy - 1
    assert geometry.orderings(fake) == 1


def test_documented_examples_load(tmp_path):
    """The JSON and TOML examples in docs/scene-format.md stay valid."""
    import shutil

    text = (ROOT / "docs" / "scene-format.md").read_text()
    shutil.copytree(ROOT / "examples" / "meshes", tmp_path / "meshes")
    blocks = {suffix: re.findall(rf"```{suffix}\n(.*?)```", text, re.S) for suffix in ("json", "toml")}
    for suffix, found in blocks.items():
        block = next(b for b in found if "showroom" in b)
        (tmp_path / f"doc.{suffix}").write_text(block)
        assert load_scene(tmp_path / f"doc.{suffix}").name == "showroom"
    # The instances example, a mesh entry, in a scene with the materials it names.
    instances = next(b for b in blocks["toml"] if "instances" in b)
    (tmp_path / "instances.toml").write_text('camera = { origin = [0, 1, 5], target = [0, 0, 0] }\n'
                                             '[materials.pine]\n[materials.larch]\n' + instances)
    scene = load_scene(tmp_path / "instances.toml")
    assert [m.name for m in scene.meshes] == ["tree[0]", "tree[1]", "swaying"] and scene.has_instances


def test_the_mesh_scene_fits_a_file_by_where_its_nodes_place_it(tmp_path):
    """The `mesh` built-in sizes a file by its placed parts: two unit boxes 9 apart fit the room together
    (sized by the untransformed box they overflowed the room ninefold) and stand on its floor."""
    group = trimesh.Scene()
    box = trimesh.creation.box(extents=(1, 1, 1))
    group.add_geometry(box, geom_name="box", node_name="left", transform=translate([-4.5, 0, 0]))
    group.graph.update(frame_to="right", frame_from=group.graph.base_frame, geometry="box",
                       matrix=translate([4.5, 0, 0]))
    group.export(tmp_path / "pair.glb")
    scene = load_scene("mesh", mesh=tmp_path / "pair.glb")
    world = np.concatenate([transform_points(m.transform, m.vertices) for m in scene.meshes
                            if m.name.startswith("pair")])
    assert np.ptp(world[:, 0]) == pytest.approx(1.2, rel=1e-5)          # the fitted width
    assert world[:, 1].min() == pytest.approx(-1.0, abs=1e-5)          # on the floor
    assert np.abs(world[:, [0, 2]]).max() < 1.0                        # inside the walls


def _colored_ply(path, kind: str):
    """A PLY of a quad with an 8-bit sRGB colour per vertex (kind "vertex") or per face ("face")."""
    import trimesh

    vertices = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    if kind == "vertex":
        mesh.visual.vertex_colors = np.array([[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255],
                                              [128, 128, 128, 255]], np.uint8)
    else:
        mesh.visual.face_colors = np.array([[200, 100, 50, 255], [200, 100, 50, 255]], np.uint8)
    mesh.export(path)


@pytest.mark.parametrize("kind", ["vertex", "face"])
def test_a_mesh_files_colours_are_read_as_linear_vertex_colours_unless_turned_off(tmp_path, kind):
    from wgpu_rt.scene.model import linear_from_srgb8
    from wgpu_rt.trace.features import SceneFeatures

    _colored_ply(tmp_path / "quad.ply", kind)
    data = {**MINIMAL, "meshes": [{"file": "quad.ply", "material": "white"}]}
    scene = load_scene(write_json(tmp_path, data))
    expected = ([[255, 0, 0], [0, 255, 0], [0, 0, 255], [128, 128, 128]] if kind == "vertex"
                else [[200, 100, 50]] * 4)
    np.testing.assert_allclose(scene.meshes[0].colors, linear_from_srgb8(np.array(expected)), rtol=1e-6)
    assert SceneFeatures.of(scene).has_surface_colors
    off = load_scene(write_json(tmp_path, {**data, "meshes": [{**data["meshes"][0], "vertex_colors": False}]}))
    assert off.meshes[0].colors is None and not SceneFeatures.of(off).has_surface_colors
    assert load_scene(write_json(tmp_path, MINIMAL)).meshes[0].colors is None   # a primitive has none


def test_vertex_colors_flag_must_be_a_boolean(tmp_path):
    _colored_ply(tmp_path / "quad.ply", "vertex")
    data = {**MINIMAL, "meshes": [{"file": "quad.ply", "material": "white", "vertex_colors": "yes"}]}
    with pytest.raises(SceneError, match=r"meshes\[0\]\.vertex_colors: expected true or false, got 'yes'"):
        load_scene(write_json(tmp_path, data))


def test_srgb8_codes_round_trip_and_follow_the_srgb_curve():
    from wgpu_rt.scene.model import linear_from_srgb8, srgb8

    codes = np.arange(256, dtype=np.uint8)
    np.testing.assert_array_equal(srgb8(linear_from_srgb8(codes)), codes)
    np.testing.assert_allclose(linear_from_srgb8(np.array([0, 128, 255])), [0.0, 0.2158605, 1.0], rtol=1e-5)


def test_vertex_colors_of_the_wrong_shape_are_refused_by_mesh_name():
    scene = load_scene("cornell")
    scene.meshes[1].colors = np.ones((3, 3), np.float32)
    with pytest.raises(SceneError, match="mesh 'floor': colors must be finite, one RGB a vertex"):
        GeometryBuffers.build(scene)


def test_a_scene_with_its_light_scaled_renders_scaled(gpu):
    """Every source (emission, point and sun lights, background) is scaled and nothing else, the original
    is left alone, and the copy renders exactly scaled (a power of two: the same paths, each sample scaled)."""
    from wgpu_rt.renderer import render
    from wgpu_rt.scene.builtin import builtin_scene
    from wgpu_rt.scene.model import DirectionalLight, PointLight

    scene = builtin_scene("cornell")
    scene.lights = [PointLight(np.float32([0.3, 0.6, 0.5]), np.float32([2.0, 1.5, 1.0])),
                    DirectionalLight(np.float32([-0.3, -0.4, -1.0]), np.float32([0.8, 0.8, 0.9]))]
    scene.background = np.float32([0.1, 0.2, 0.3])
    emission = {name: material.emission.copy() for name, material in scene.materials.items()}
    dim = scene.with_light_scaled(2.0 ** -5)
    for name, material in dim.materials.items():
        np.testing.assert_array_equal(material.emission, emission[name] / 32)
        np.testing.assert_array_equal(scene.materials[name].emission, emission[name])
        np.testing.assert_array_equal(material.reflectance, scene.materials[name].reflectance)
    np.testing.assert_array_equal(dim.lights[0].intensity, np.float32([2.0, 1.5, 1.0]) / 32)
    np.testing.assert_array_equal(dim.lights[1].irradiance, np.float32([0.8, 0.8, 0.9]) / 32)
    np.testing.assert_array_equal(dim.lights[1].direction, scene.lights[1].direction)
    np.testing.assert_array_equal(dim.background, scene.background / 32)
    assert dim.meshes is scene.meshes and dim.camera is scene.camera
    options = dict(size=(12, 10), max_depth=3, ctx=gpu, aovs=())
    np.testing.assert_array_equal(render(dim, **options).color * 32, render(scene, **options).color)


def test_glass_takes_a_transmittance(tmp_path):
    """A dielectric's ``transmittance`` tints what crosses it (default white); above 1 it is refused by field."""
    from wgpu_rt.scene.loader import parse_scene

    data = {"camera": {"origin": [0, 0, 3], "target": [0, 0, 0]},
            "materials": {"bottle": {"kind": "dielectric", "transmittance": [0.3, 0.7, 0.4]},
                          "clear": {"kind": "dielectric"}},
            "meshes": [{"shape": "sphere", "material": "bottle"}, {"shape": "cube", "material": "clear"}],
            "lights": [{"type": "point", "position": [0, 2, 2], "intensity": 1}]}
    materials = parse_scene(data, "scene.json", tmp_path).materials
    np.testing.assert_allclose(materials["bottle"].transmittance, [0.3, 0.7, 0.4])
    np.testing.assert_array_equal(materials["clear"].transmittance, [1, 1, 1])
    data["materials"]["bottle"]["transmittance"] = 1.2
    with pytest.raises(SceneError, match=r"materials\.bottle: transmittance must be in \[0, 1\]"):
        parse_scene(data, "scene.json", tmp_path)


def test_glass_takes_an_absorption_and_nothing_else_does(tmp_path):
    """A dielectric's ``absorption`` (per unit length, each channel ≥ 0; default none); a negative one, or one on
    another kind of material, is refused by field."""
    from wgpu_rt.scene.loader import parse_scene

    data = {"camera": {"origin": [0, 0, 3], "target": [0, 0, 0]},
            "materials": {"bottle": {"kind": "dielectric", "absorption": [0.3, 2.0, 0.0]},
                          "clear": {"kind": "dielectric"}},
            "meshes": [{"shape": "sphere", "material": "bottle"}, {"shape": "cube", "material": "clear"}]}
    materials = parse_scene(data, "scene.json", tmp_path).materials
    np.testing.assert_allclose(materials["bottle"].absorption, [0.3, 2.0, 0.0])
    assert materials["bottle"].absorbs and not materials["clear"].absorbs
    data["materials"]["bottle"]["absorption"] = -1
    with pytest.raises(SceneError, match=r"materials\.bottle: absorption must be non-negative"):
        parse_scene(data, "scene.json", tmp_path)
    data["materials"]["bottle"] = {"kind": "plastic", "absorption": 1}
    with pytest.raises(SceneError, match=r"materials\.bottle: absorption is a dielectric's .*not a plastic's"):
        parse_scene(data, "scene.json", tmp_path)


def test_a_plastic_coat_may_be_rough(tmp_path):
    """A plastic's coat is smooth by default (Mitsuba's plastic) and takes a GGX roughness (its roughplastic);
    one outside [0, 1] is refused by field."""
    from wgpu_rt.scene.loader import parse_scene

    data = {"camera": {"origin": [0, 0, 3], "target": [0, 0, 0]},
            "materials": {"coated": {"kind": "plastic", "reflectance": 0.4, "ior": 1.4}},
            "meshes": [{"shape": "cube", "material": "coated"}], "lights": [{"type": "point", "position": [0, 2, 2],
                                                                           "intensity": 1}]}
    assert parse_scene(data, "scene.json", tmp_path).materials["coated"].roughness == 0.0
    data["materials"]["coated"]["roughness"] = 0.2
    assert parse_scene(data, "scene.json", tmp_path).materials["coated"].roughness == pytest.approx(0.2)
    data["materials"]["coated"]["roughness"] = 1.5
    with pytest.raises(SceneError, match=r"materials\.coated: roughness must be in \[0, 1\]"):
        parse_scene(data, "scene.json", tmp_path)
