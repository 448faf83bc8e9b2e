"""A glTF file's node animations (wgpu_rt/scene/gltf_animation.py) move a scene file's meshes and camera frame by
frame: translation, rotation (slerp) and scale channels, LINEAR, STEP and CUBICSPLINE, FRAME_RATE frames a second."""

import numpy as np
import pytest
import trimesh
from gltf_files import with_accessors

from wgpu_rt.errors import SceneError
from wgpu_rt.scene import load_scene
from wgpu_rt.scene.gltf_animation import FRAME_RATE

CAMERA = {"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.1}}
HALF_TURN_ABOUT_Y = [0.0, 1.0, 0.0, 0.0]
STAGE = '[camera]\norigin = [0, 2, 12]\ntarget = [0, 0, 0]\n\n[materials.white]\nreflectance = 0.8\n\n'


def _animated(tmp_path, channels, arrays, name="moving.glb", lamp=None):
    """Two boxes (nodes 0 and 1, the second 3 units along x), with ``lamp`` a node "lamp" at (0, 3, 0) holding that
    KHR_lights_punctual light, and a camera at (0, 1, 8) (the last node); ``channels`` are (node, path,
    interpolation, input, output) with input and output indices into ``arrays``, appended as accessors."""
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box(extents=(1, 1, 1)), node_name="still")
    scene.add_geometry(trimesh.creation.box(extents=(0.5, 0.5, 0.5)), node_name="mover",
                       transform=trimesh.transformations.translation_matrix([3, 0, 0]))

    def edit(tree, first):
        if lamp is not None:
            tree["nodes"].append({"name": "lamp", "translation": [0, 3, 0],
                                  "extensions": {"KHR_lights_punctual": {"light": 0}}})
            tree["scenes"][0]["nodes"].append(len(tree["nodes"]) - 1)
            tree["extensions"] = {"KHR_lights_punctual": {"lights": [lamp]}}
        tree["nodes"].append({"camera": 0, "translation": [0, 1, 8]})
        tree["scenes"][0]["nodes"].append(len(tree["nodes"]) - 1)
        tree["cameras"] = [CAMERA]
        names = [node.get("name") for node in tree["nodes"]]
        samplers, targets = [], []
        for node, path, interpolation, given, taken in channels:
            index = names.index(node) if isinstance(node, str) else len(tree["nodes"]) - 1
            samplers.append({"input": first + given, "output": first + taken, "interpolation": interpolation})
            targets.append({"sampler": len(samplers) - 1, "target": {"node": index, "path": path}})
        tree["animations"] = [{"samplers": samplers, "channels": targets}]

    data = scene.export(file_type="glb")
    (tmp_path / name).write_bytes(with_accessors(data, arrays, edit))
    return load_scene(tmp_path / name)


def _mover(scene):
    return next(mesh for mesh in scene.meshes if mesh.name.endswith("mover"))


def test_a_linear_translation_moves_its_mesh_frame_by_frame(tmp_path):
    """Keys at 0 and 1 s: 25 frames at 24 a second, the box at (3 + 2 t, 0, 0), the other box and the camera still."""
    scene = _animated(tmp_path, [("mover", "translation", "LINEAR", 0, 1)],
                      [[0.0, 1.0], [[3, 0, 0], [5, 0, 0]]])
    assert scene.frame_count == int(FRAME_RATE) + 1 and not scene.camera_keyframes
    mover, still = _mover(scene), next(m for m in scene.meshes if m.name.endswith("still"))
    for frame in (0, 6, 24):
        np.testing.assert_allclose(mover.transform_at(frame)[:3, 3], [3 + 2 * frame / FRAME_RATE, 0, 0], atol=1e-5)
    assert not still.keyframes and scene.has_motion


def test_step_and_cubic_spline_keys(tmp_path):
    """STEP holds a key until the next; CUBICSPLINE with flat tangents eases between keys (smoothstep: at a quarter
    of the way, 5/32 of the distance)."""
    scene = _animated(tmp_path, [("mover", "translation", "STEP", 0, 1)], [[0.0, 1.0], [[3, 0, 0], [5, 0, 0]]])
    np.testing.assert_allclose(_mover(scene).transform_at(23)[:3, 3], [3, 0, 0], atol=1e-5)
    np.testing.assert_allclose(_mover(scene).transform_at(24)[:3, 3], [5, 0, 0], atol=1e-5)
    cubic = [[0, 0, 0], [3, 0, 0], [0, 0, 0], [0, 0, 0], [5, 0, 0], [0, 0, 0]]   # in-tangent, value, out-tangent
    scene = _animated(tmp_path, [("mover", "translation", "CUBICSPLINE", 0, 1)], [[0.0, 1.0], cubic])
    np.testing.assert_allclose(_mover(scene).transform_at(6)[:3, 3], [3 + 2 * 5 / 32, 0, 0], atol=1e-5)


def test_a_rotation_slerps_and_a_camera_follows_its_node(tmp_path):
    """A half turn about +y over 2 s passes an eighth of a turn at 0.5 s (slerp: an element-wise blend of the
    quaternions would have turned 36.9°) and a quarter at 1 s; a camera node moved along x takes the scene's camera
    with it, frame by frame."""
    scene = _animated(tmp_path, [("mover", "rotation", "LINEAR", 0, 1), (None, "translation", "LINEAR", 0, 2)],
                      [[0.0, 2.0], [[0, 0, 0, 1], HALF_TURN_ABOUT_Y], [[0, 1, 8], [4, 1, 8]]])
    assert scene.frame_count == 2 * int(FRAME_RATE) + 1
    for frame, degrees in ((12, 45.0), (24, 90.0)):
        turned = _mover(scene).transform_at(frame)[:3, :3] @ [1, 0, 0]
        np.testing.assert_allclose(turned, [np.cos(np.radians(degrees)), 0, -np.sin(np.radians(degrees))], atol=1e-5)
        # (its node's own translation, written by trimesh as a matrix, kept where only its rotation is animated)
        np.testing.assert_allclose(_mover(scene).transform_at(frame)[:3, 3], [3, 0, 0], atol=1e-5)
    np.testing.assert_allclose(scene.camera_at(24).origin, [2, 1, 8], atol=1e-5)
    np.testing.assert_allclose(scene.camera_at(48).origin, [4, 1, 8], atol=1e-5)
    np.testing.assert_allclose(scene.camera.origin, [0, 1, 8], atol=1e-5)


def test_a_light_follows_its_animated_node(tmp_path):
    """A spot on a node that slides along x and turns a quarter about x over 1 s: at each frame the light sits where
    its node is and shines down the node's −z (slerped: the angle in step with time); the boxes stay still."""
    quarter_about_x = [np.sin(np.pi / 4), 0.0, 0.0, np.cos(np.pi / 4)]
    scene = _animated(tmp_path, [("lamp", "translation", "LINEAR", 0, 1), ("lamp", "rotation", "LINEAR", 0, 2)],
                      [[0.0, 1.0], [[0, 3, 0], [2, 3, 0]], [[0, 0, 0, 1], quarter_about_x]],
                      lamp={"type": "spot", "intensity": 683.0, "spot": {"outerConeAngle": 0.5}})
    assert scene.has_moving_lights and not scene.has_motion and scene.frame_count == int(FRAME_RATE) + 1
    for frame in (0, 12, 24):
        spot = scene.lights_at(frame)[0]
        t = frame / FRAME_RATE
        np.testing.assert_allclose(spot.position, [2 * t, 3, 0], atol=1e-5)
        angle = np.pi / 2 * t
        np.testing.assert_allclose(spot.direction, [0, np.sin(angle), -np.cos(angle)], atol=1e-5)
    still = _animated(tmp_path, [("mover", "translation", "LINEAR", 0, 1)], [[0.0, 1.0], [[3, 0, 0], [5, 0, 0]]],
                      lamp={"type": "point"})
    assert not still.has_moving_lights and not still.lights[0].keyframes


@pytest.mark.parametrize("arrays, message", [
    ([[0.0, 1.0], [[3, 0, 0]]], r"animation 0 channel 0: 2 key times but 1 values of 3 for its linear translation"),
    ([[1.0, 0.0], [[3, 0, 0], [5, 0, 0]]], r"animation 0 channel 0: key times must rise"),
    ([[0.0, 4000.0], [[3, 0, 0], [5, 0, 0]]], r"moving.glb: its animations run 4000 s, longer than the 3600 s read"),
])
def test_bad_animations_are_refused_by_channel(tmp_path, arrays, message):
    with pytest.raises(SceneError, match=message):
        _animated(tmp_path, [("mover", "translation", "LINEAR", 0, 1)], arrays)


def test_the_turntable_example_turns_its_box_and_moves_its_camera_in():
    """examples/meshes/turntable.glb (make_turntable.py): 49 frames; the brass box, under its metallic-roughness
    texture, a full turn over them (a quarter at frame 12); the camera a unit nearer at the end; the rest still."""
    from pathlib import Path

    scene = load_scene(Path(__file__).resolve().parents[1] / "examples" / "meshes" / "turntable.glb")
    assert scene.frame_count == 49 and scene.name == "gltf:turntable.glb"
    box = next(mesh for mesh in scene.meshes if mesh.name.endswith("brass-box"))
    assert box.metal_rough_map is not None and scene.materials[box.material].kind == "plastic"
    np.testing.assert_allclose(box.transform_at(12)[:3, :3] @ [1, 0, 0], [0, 0, -1], atol=1e-5)
    np.testing.assert_allclose(box.transform_at(48), box.transform_at(0), atol=1e-5)
    assert all(not mesh.keyframes for mesh in scene.meshes if mesh is not box)
    start, end = scene.camera_at(0), scene.camera_at(48)
    assert np.linalg.norm(start.origin - start.target) == pytest.approx(1.0, abs=1e-5)   # (target: a unit ahead)
    assert np.linalg.norm(end.origin - np.float32([0, 0.6, 0])) < np.linalg.norm(start.origin - np.float32([0, 0.6, 0]))


def test_a_scene_files_entry_plays_its_glb_animation_under_its_transform(tmp_path):
    """A glTF file placed by a scene file's mesh entry moves as the file animates it, under the entry's transform
    (here lifted by 1 and scaled by 2), and the scene has the animation's frames; an entry with keyframes of its
    own takes those instead."""
    _animated(tmp_path, [("mover", "translation", "LINEAR", 0, 1)], [[0.0, 1.0], [[3, 0, 0], [5, 0, 0]]])
    entry = '[[meshes]]\nfile = "moving.glb"\nmaterial = "white"\ntransform = { scale = 2.0, translate = [0, 1, 0] }\n'
    (tmp_path / "stage.toml").write_text(STAGE + entry)
    scene = load_scene(tmp_path / "stage.toml")
    assert scene.frame_count == int(FRAME_RATE) + 1
    np.testing.assert_allclose(_mover(scene).transform_at(12)[:3, 3], [2 * 4, 1, 0], atol=1e-5)
    keyed = entry + 'keyframes = [{ frame = 0 }, { frame = 4, translate = [0, 3, 0] }]\n'
    (tmp_path / "stage.toml").write_text(STAGE + keyed)
    scene = load_scene(tmp_path / "stage.toml")
    assert scene.frame_count == 5
    np.testing.assert_allclose(_mover(scene).transform_at(4)[:3, 3], [3, 3, 0], atol=1e-5)


def test_instances_of_an_animated_glb_each_play_its_animation_under_their_placement(tmp_path):
    """Placed twice by `instances`, the file's animation moves each instance's parts under its own placement (1 up,
    and 4 along x and half-size); an instance with keyframes of its own takes those instead."""
    _animated(tmp_path, [("mover", "translation", "LINEAR", 0, 1)], [[0.0, 1.0], [[3, 0, 0], [5, 0, 0]]])
    entry = ('[[meshes]]\nfile = "moving.glb"\nmaterial = "white"\ntransform = { translate = [0, 1, 0] }\n'
             'instances = [{ name = "a" }, { name = "b", transform = { scale = 0.5, translate = [4, 0, 0] } }, '
             '{ name = "c", keyframes = [{ frame = 0 }, { frame = 2, translate = [0, 0, 1] }] }]\n')
    (tmp_path / "stage.toml").write_text(STAGE + entry)
    scene = load_scene(tmp_path / "stage.toml")
    movers = {mesh.name.split("/")[0]: mesh for mesh in scene.meshes if mesh.name.endswith("mover")}
    np.testing.assert_allclose(movers["a"].transform_at(12)[:3, 3], [4, 1, 0], atol=1e-5)
    np.testing.assert_allclose(movers["b"].transform_at(12)[:3, 3], [4 + 0.5 * 4, 0.5, 0], atol=1e-5)
    np.testing.assert_allclose(movers["c"].transform_at(12)[:3, 3], [3, 1, 1], atol=1e-5)     # its own keys
    assert scene.has_instances


def test_the_mesh_room_plays_a_glb_animation_fitted_by_its_rest_pose(tmp_path):
    """`load_scene("mesh", mesh=...)`: the file fitted into the room by its rest pose, its animation then playing
    at that fit (the mover's 2 units of travel scaled by it), for the animation's frames."""
    _animated(tmp_path, [("mover", "translation", "LINEAR", 0, 1)], [[0.0, 1.0], [[3, 0, 0], [5, 0, 0]]])
    scene = load_scene("mesh", mesh=tmp_path / "moving.glb")
    assert scene.frame_count == int(FRAME_RATE) + 1 and scene.has_motion
    mover = _mover(scene)
    fit = mover.transform[0, 0] / 1.0          # (the box's rest placement: the fit's scale, no rotation)
    travel = mover.transform_at(24)[:3, 3] - mover.transform_at(0)[:3, 3]
    np.testing.assert_allclose(travel, [2 * fit, 0, 0], atol=1e-5)
    np.testing.assert_allclose(mover.transform_at(0), mover.transform, atol=1e-6)


def test_alternative_clips_play_the_first_or_the_one_picked(tmp_path):
    """Two animations moving the same node's translation (clips: "left" then "right") are alternatives: the first
    plays unless `animation` picks the other by name or index; animations of different nodes play together."""
    path = tmp_path / "clips.glb"

    def clips(tree, first):
        mover = next(i for i, node in enumerate(tree["nodes"]) if node.get("name") == "mover")
        tree["animations"] = [
            {"name": name, "samplers": [{"input": first, "output": first + offset}],
             "channels": [{"sampler": 0, "target": {"node": mover, "path": "translation"}}]}
            for name, offset in (("left", 1), ("right", 2))]

    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box(extents=(0.5, 0.5, 0.5)), node_name="mover",
                       transform=trimesh.transformations.translation_matrix([3, 0, 0]))
    arrays = [[0.0, 1.0], [[3, 0, 0], [1, 0, 0]], [[3, 0, 0], [5, 0, 0]]]
    path.write_bytes(with_accessors(scene.export(file_type="glb"), arrays, clips))
    for choice, end in ((None, 1), ("right", 5), ("1", 5), ("0", 1)):
        room = load_scene("mesh", mesh=path, animation=choice)
        (box,) = [mesh for mesh in room.meshes if mesh.name.startswith("clips")]
        travel = (box.transform_at(24)[0, 3] - box.transform_at(0)[0, 3]) / box.transform[0, 0]
        assert travel == pytest.approx(end - 3, abs=1e-5), choice
    with pytest.raises(SceneError, match=r"clips.glb: no animation 'walk'; its animations: 0 \(left\), 1 \(right\)"):
        load_scene("mesh", mesh=path, animation="walk")
    with pytest.raises(SceneError, match=r"an animation choice \(animation=/--animation 0\) is for a glTF file"):
        load_scene("cornell", animation="0")
    def broken_second(tree, first):     # a clip not played is not read: its bad sampler stops nothing
        clips(tree, first)
        tree["animations"][1]["channels"][0]["sampler"] = 9

    path.write_bytes(with_accessors(scene.export(file_type="glb"), arrays, broken_second))
    assert load_scene("mesh", mesh=path, animation="left").has_motion
    with pytest.raises(SceneError, match=r"animation 1 channel 0: sampler 9 is not one of the animation's 1"):
        load_scene("mesh", mesh=path, animation="right")
    path.write_bytes(with_accessors(scene.export(file_type="glb"), arrays, clips))
    entry = '[[meshes]]\nfile = "clips.glb"\nmaterial = "white"\nanimation = "right"\n'
    (tmp_path / "stage.toml").write_text(STAGE + entry)
    (box,) = [mesh for mesh in load_scene(tmp_path / "stage.toml").meshes if mesh.name.startswith("clips")]
    assert box.transform_at(24)[0, 3] == pytest.approx(5, abs=1e-5)
    (tmp_path / "stage.toml").write_text(STAGE + entry.replace('"right"', "true"))
    with pytest.raises(SceneError, match=r"meshes\[0\].animation: expected the index or name of one of a glTF"):
        load_scene(tmp_path / "stage.toml")

    def apart(tree, first):      # "left" on the mover, another animation on a second box: no conflict, both play
        clips(tree, first)
        other = next(i for i, node in enumerate(tree["nodes"]) if node.get("name") == "other")
        tree["animations"][1]["channels"][0]["target"]["node"] = other

    scene.add_geometry(trimesh.creation.box(extents=(0.3, 0.3, 0.3)), node_name="other")
    path.write_bytes(with_accessors(scene.export(file_type="glb"), arrays, apart))
    room = load_scene("mesh", mesh=path)
    assert sum(mesh.is_animated for mesh in room.meshes) == 2
