"""A glTF file with a camera is a scene of its own (wgpu_rt/scene/gltf_scene.py): its camera, its
KHR_lights_punctual lights in the tracer's units, its meshes where its nodes put them."""

import numpy as np
import pytest
import trimesh
from gltf_files import edit_glb_json

from wgpu_rt.errors import SceneError
from wgpu_rt.renderer import render
from wgpu_rt.scene import DirectionalLight, PointLight, SpotLight, load_scene

QUARTER_TURN_ABOUT_Y = [0.0, np.sin(np.pi / 4), 0.0, np.cos(np.pi / 4)]   # glTF's (x, y, z, w)


def _glb(tmp_path, nodes=(), cameras=(), lights=(), floor=False, name="room.glb"):
    """A unit box at the origin (a grey floor of 4 × 4 at y = −0.5 below it with ``floor``), plus ``nodes`` (those
    no node names as a child added to the scene's roots) with ``cameras`` and ``lights`` (KHR_lights_punctual)
    for them to name."""
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box(extents=(1, 1, 1)), node_name="box")
    if floor:
        plane = trimesh.creation.box(extents=(4, 0.01, 4))
        plane.apply_translation((0, -0.505, 0))
        scene.add_geometry(plane, node_name="floor")

    def edit(tree):
        first = len(tree["nodes"])
        tree["nodes"] += list(nodes)
        children = {child for node in nodes for child in node.get("children", [])}
        tree["scenes"][0]["nodes"] += [first + i for i in range(len(nodes)) if first + i not in children]
        if cameras:
            tree["cameras"] = list(cameras)
        if lights:
            tree.setdefault("extensions", {})["KHR_lights_punctual"] = {"lights": list(lights)}

    (tmp_path / name).write_bytes(edit_glb_json(scene.export(file_type="glb"), edit))
    return tmp_path / name


CAMERA = {"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.1}}


def test_the_files_camera_sees_its_meshes_where_its_nodes_put_them(tmp_path):
    """A camera node turned a quarter about +y at (4, 0, 0) looks down −x at the box (glTF cameras look down −z),
    with the file's vertical field of view; the box stays where the file puts it (no room, no fitting)."""
    path = _glb(tmp_path, nodes=[{"camera": 0, "translation": [4, 0, 0], "rotation": QUARTER_TURN_ABOUT_Y}],
                cameras=[CAMERA])
    scene = load_scene(path)
    np.testing.assert_allclose(scene.camera.origin, [4, 0, 0], atol=1e-6)
    direction = (scene.camera.target - scene.camera.origin) / np.linalg.norm(scene.camera.target - scene.camera.origin)
    np.testing.assert_allclose(direction, [-1, 0, 0], atol=1e-6)
    np.testing.assert_allclose(scene.camera.up, [0, 1, 0], atol=1e-6)
    assert scene.camera.fov_axis == "y" and scene.camera.fov == pytest.approx(np.degrees(0.5))
    assert [mesh.name for mesh in scene.meshes] == ["room"]
    np.testing.assert_array_equal(scene.meshes[0].transform, np.eye(4))


def test_a_camera_under_a_parent_node_takes_the_parents_placement(tmp_path):
    """A node's world transform is its parents' times its own (a matrix, column-major, on the parent)."""
    parent = {"matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 2, 0, 1], "children": [2]}   # 2 up
    path = _glb(tmp_path, nodes=[parent, {"camera": 0, "translation": [0, 0, 5]}], cameras=[CAMERA])
    scene = load_scene(path)
    np.testing.assert_allclose(scene.camera.origin, [0, 2, 5], atol=1e-6)
    np.testing.assert_allclose(scene.camera.target - scene.camera.origin, [0, 0, -1], atol=1e-6)


def test_a_file_without_a_camera_stays_an_object_in_the_mesh_room(tmp_path):
    scene = load_scene(_glb(tmp_path))
    assert scene.name == "mesh:room.glb" and len(scene.meshes) > 1


def test_punctual_lights_come_in_the_tracers_units(tmp_path):
    """Candela and lux over 683 lm/W, times the colour; directional and spot lights point down their node's −z; a
    spot's outer and inner cone angles are its cut-off and beam width; with lights the background is black."""
    lights = [{"type": "point", "intensity": 683.0, "color": [1.0, 0.5, 0.25]},
              {"type": "directional", "intensity": 1366.0},
              {"type": "spot", "intensity": 68.3, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.6}}]
    nodes = [{"camera": 0, "translation": [0, 0, 5]},
             {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [1, 2, 3]},
             {"extensions": {"KHR_lights_punctual": {"light": 1}}, "rotation": QUARTER_TURN_ABOUT_Y},
             {"extensions": {"KHR_lights_punctual": {"light": 2}}, "translation": [0, 3, 0],
              "rotation": [-np.sin(np.pi / 4), 0.0, 0.0, np.cos(np.pi / 4)]}]     # −z turned to −y: down
    scene = load_scene(_glb(tmp_path, nodes=nodes, cameras=[CAMERA], lights=lights))
    point, sun, spot = scene.lights
    assert type(point) is PointLight and isinstance(sun, DirectionalLight) and isinstance(spot, SpotLight)
    np.testing.assert_allclose(point.position, [1, 2, 3], atol=1e-6)
    np.testing.assert_allclose(point.intensity, [1.0, 0.5, 0.25], rtol=1e-6)
    np.testing.assert_allclose(sun.direction, [-1, 0, 0], atol=1e-6)
    np.testing.assert_allclose(sun.irradiance, [2, 2, 2], rtol=1e-6)
    np.testing.assert_allclose(spot.direction, [0, -1, 0], atol=1e-6)
    np.testing.assert_allclose(spot.intensity, [0.1, 0.1, 0.1], rtol=1e-6)
    assert spot.cutoff_angle == pytest.approx(np.degrees(0.6)) and spot.beam_width == pytest.approx(np.degrees(0.2))
    np.testing.assert_array_equal(scene.background, [0, 0, 0])


def test_a_file_without_lights_is_lit_by_a_white_sky(tmp_path):
    scene = load_scene(_glb(tmp_path, nodes=[{"camera": 0, "translation": [0, 0, 5]}], cameras=[CAMERA]))
    assert scene.lights == [] and np.all(scene.background == 1.0)


def test_a_point_light_renders_at_its_intensity_over_683(gpu, tmp_path):
    """The floor straight below a point light of 683·π cd at height 2, seen from above, direct light only: the
    clay's radiance there is 0.7/π · π/2² = 0.175 (the box hidden away)."""
    nodes = [{"camera": 0, "translation": [1.5, 3, 1.5], "rotation": [-np.sin(np.pi / 4), 0.0, 0.0, np.cos(np.pi / 4)]},
             {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [1.5, 1.5, 1.5]}]
    camera = {"type": "perspective", "perspective": {"yfov": 0.02}}
    path = _glb(tmp_path, nodes=nodes, cameras=[camera], lights=[{"type": "point", "intensity": 683 * np.pi}],
                floor=True)
    color = render(load_scene(path), spp=4, size=(8, 8), max_depth=2, aovs=()).color
    np.testing.assert_allclose(color[3:5, 3:5], 0.175, rtol=2e-3)


@pytest.mark.parametrize("change, message", [
    (lambda tree: tree["cameras"][0].update(type="orthographic"),
     r"camera 0 \(node 1\): a 'orthographic' camera; only perspective cameras are rendered"),
    (lambda tree: tree["cameras"][0]["perspective"].pop("yfov"), r"camera 0 \(node 1\): a perspective camera without"),
    (lambda tree: tree["nodes"][1].update(camera=3), r"camera 3 \(node 1\): not one of the file's 1 cameras"),
    (lambda tree: tree["nodes"][1].update(children=[1]), r"node 1 is reached twice"),
    (lambda tree: tree["nodes"][1].update(translation=[0, "x", 0]), r"node 1: translation must be numbers"),
    (lambda tree: tree["extensions"]["KHR_lights_punctual"]["lights"][0].update(type="area"),
     r"light 0 \(node 2\): unknown light type 'area'"),
    (lambda tree: tree["extensions"]["KHR_lights_punctual"]["lights"][0].update(intensity=-1),
     r"light 0 \(node 2\): intensity must be in \[0, inf\]"),
    (lambda tree: tree["nodes"][0].update(matrix=[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 2e9, 0, 0, 1]),
     r"mesh 'room': its placement puts vertices beyond ±1e\+09"),
    (lambda tree: tree["nodes"][1].update(translation=[0, 0, 2e9]), r"camera 0 \(node 1\): placed beyond ±1e\+09"),
])
def test_a_bad_camera_node_light_or_placement_is_refused_by_name(tmp_path, change, message):
    path = _glb(tmp_path, nodes=[{"camera": 0, "translation": [0, 0, 5]},
                                 {"extensions": {"KHR_lights_punctual": {"light": 0}}}],
                cameras=[CAMERA], lights=[{"type": "point"}])
    path.write_bytes(edit_glb_json(path.read_bytes(), change))
    with pytest.raises(SceneError, match=r"room\.glb: " + message):
        load_scene(path)


def test_the_gallery_example_is_a_scene_of_its_own():
    """examples/meshes/gallery.glb (examples/meshes/make_gallery.py): its camera, its three lights, its glass ball
    absorbing inside by its volume extension."""
    from pathlib import Path

    scene = load_scene(Path(__file__).resolve().parents[1] / "examples" / "meshes" / "gallery.glb")
    assert scene.name == "gltf:gallery.glb" and scene.camera.fov_axis == "y"
    assert sorted(type(light).__name__ for light in scene.lights) == ["DirectionalLight", "PointLight", "SpotLight"]
    assert scene.materials["gallery/amber"].kind == "dielectric" and scene.materials["gallery/amber"].absorbs
    np.testing.assert_array_equal(scene.background, [0, 0, 0])


def test_a_camera_is_picked_by_its_index_or_its_name_or_its_nodes(tmp_path):
    """With two cameras, the first placed is taken unless ``camera`` names another: by its index in the file's
    cameras, its name or its node's; an unknown one is refused listing them, and a scene without glTF cameras
    refuses any."""
    path = _glb(tmp_path, nodes=[{"camera": 0, "translation": [0, 0, 4]},
                                 {"name": "side", "camera": 1, "translation": [4, 0, 0],
                                  "rotation": QUARTER_TURN_ABOUT_Y}],
                cameras=[CAMERA, {**CAMERA, "name": "wide", "perspective": {"yfov": 1.0}}])
    np.testing.assert_allclose(load_scene(path).camera.origin, [0, 0, 4], atol=1e-6)
    for choice in ("1", "wide", "side"):
        scene = load_scene(path, camera=choice)
        np.testing.assert_allclose(scene.camera.origin, [4, 0, 0], atol=1e-6)
        assert scene.camera.fov == pytest.approx(np.degrees(1.0))
    with pytest.raises(SceneError, match=r"room.glb: no camera 'top'; its cameras: 0 \(node \d+\), 1 \(side\)"):
        load_scene(path, camera="top")
    with pytest.raises(SceneError, match=r"cornell: a camera choice \(camera=/--camera top\) is for a glTF file"):
        load_scene("cornell", camera="top")
