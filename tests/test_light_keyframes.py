"""Animated lights: a scene file's light ``keyframes`` (a glTF light follows its node: tests/test_gltf_animation.py)
change a light's place, aim, strength and cone frame by frame. The tracer's emitter table follows them, so a frame of
an animated scene renders as the still scene of that frame's lights; temporal accumulation does not take a still
view under a changing light for one that converges."""

from pathlib import Path

import numpy as np
import pytest

from wgpu_rt.errors import SceneError
from wgpu_rt.frame.temporal import frame_change
from wgpu_rt.renderer import render
from wgpu_rt.scene.loader import parse_scene
from wgpu_rt.scene.model import Scene

FLOOR = {"shape": "rectangle", "material": "white", "transform": {"rotate": {"axis": [1, 0, 0], "angle": -90},
                                                                  "scale": 2}}
BOX = {"shape": "cube", "material": "white", "transform": {"translate": [0.3, 0.25, -0.2], "scale": 0.25}}


def _scene(lights, **top) -> Scene:
    data = {"camera": {"origin": [0, 3, 0.01], "target": [0, 0, 0], "fov": 60},
            "materials": {"white": {"reflectance": 0.7}}, "meshes": [FLOOR, BOX], "lights": lights, **top}
    return parse_scene(data, "lit.json", Path("."))


SWEEP = {"type": "spot", "position": [-0.8, 1.5, 0], "target": [-0.8, 0, 0], "intensity": 3, "cutoff_angle": 20,
         "keyframes": [{"frame": 0}, {"frame": 8, "position": [0.8, 1.5, 0], "direction": [0.3, -1, 0],
                                      "intensity": [6, 3, 1], "cutoff_angle": 40}]}
FADE = {"type": "point", "position": [0, 1, 0.5], "intensity": 0.5,
        "keyframes": [{"frame": 2}, {"frame": 6, "intensity": 0}]}


def test_keyframes_blend_each_field_and_set_the_frame_count():
    """Halfway between two keys every number is halfway (the direction renormalized; a key that sets the cutoff
    alone has Mitsuba's beam width, ¾ of it); before the first key and after the last the nearest key holds."""
    scene = _scene([SWEEP, FADE])
    assert scene.frame_count == 9 and scene.has_moving_lights and not scene.has_motion and scene.is_animated
    spot, lamp = scene.lights_at(4)
    np.testing.assert_allclose(spot.position, [0, 1.5, 0])
    halfway = [0, -1, 0] + np.array([0.3, -1, 0]) / np.linalg.norm([0.3, -1, 0])     # of the unit directions
    np.testing.assert_allclose(spot.direction, halfway / np.linalg.norm(halfway), rtol=1e-6)
    np.testing.assert_allclose(spot.intensity, [4.5, 3, 2])
    assert (spot.cutoff_angle, spot.beam_width) == (30.0, 0.5 * (15.0 + 30.0))
    np.testing.assert_allclose(lamp.intensity, 0.25)
    np.testing.assert_allclose(scene.lights_at(12)[0].position, [0.8, 1.5, 0])
    np.testing.assert_allclose(scene.lights_at(0)[1].intensity, 0.5)
    doubled = scene.with_light_scaled(2.0)
    np.testing.assert_allclose(doubled.lights_at(4)[0].intensity, [9, 6, 4])
    assert scene.lights_key(1) != scene.lights_key(2) and scene.lights_key(9) == scene.lights_key(10)


@pytest.mark.parametrize("light, message", [
    ({**FADE, "keyframes": [{"frame": 1, "type": "spot"}]}, r"lights\[0\].keyframes\[0\]: unknown key 'type'"),
    ({**FADE, "keyframes": [{"frame": 1}, {"frame": 1}]},
     r"lights\[0\].keyframes\[1\].frame: a second keyframe for frame 1"),
    ({**FADE, "keyframes": [{"frame": 1, "intensity": -1}]}, r"keyframes\[0\].intensity: must not be negative"),
    ({**SWEEP, "keyframes": [{"frame": 0}, {"frame": 3, "direction": [0, 1, 0]}]},
     r"lights\[0\].keyframes: turns 180° between frames 0 and 3 .* add keyframes between them"),
    ({**SWEEP, "keyframes": [{"frame": 0, "direction": [0, -1, 0], "target": [0, 0, 0]}]},
     r"keyframes\[0\]: give exactly one of 'direction'"),
    ({**SWEEP, "keyframes": [{"frame": 0, "beam_width": 25}]}, r"keyframes\[0\].beam_width: beam_width must be in"),
])
def test_bad_light_keyframes_fail_naming_the_field(light, message):
    with pytest.raises(SceneError, match=message):
        _scene([light])


def test_a_frame_renders_as_the_still_scene_of_its_lights(gpu):
    """Frames 0, 3 and 8 of the sweep and the fade, rendered in one pass (the emitter table rebuilt between them),
    equal renders of still scenes lit as each frame is, sample for sample. At frame 8 the fade is dark: it keeps
    its record (the table keeps its layout), picked by a power of 1e-30, where the still scene has none; that
    moves some pixels by a float32 rounding, no more."""
    scene = _scene([SWEEP, FADE])
    frames = [0, 3, 8]
    animated = render(scene, spp=4, size=(32, 32), max_depth=3, aovs=(), frames=frames, seed=5)
    for frame, result in zip(frames, animated):
        still = Scene(scene.camera, scene.meshes, scene.materials, scene.lights_at(frame), name="still")
        expected = render(still, spp=4, size=(32, 32), max_depth=3, aovs=(), frames=frame, seed=5).color
        if frame < 6:
            np.testing.assert_array_equal(result.color, expected)
        else:
            np.testing.assert_allclose(result.color, expected, rtol=1e-5, atol=1e-7)


def test_a_still_view_under_a_moving_light_is_not_taken_for_a_converging_one(gpu):
    """A spot that jumps between frames 3 and 4 under a still camera: the frame after the jump is 'moving' (the
    history reprojected and clamped), not 'static' (accumulated, which left the old pool of light at four fifths
    of its brightness in the frame after the jump and still half of it three frames later); once the light holds
    still the view converges again."""
    jump = {**SWEEP, "direction": [0, -1, 0], "keyframes": [{"frame": 3}, {"frame": 4, "position": [0.8, 1.5, 0]}]}
    del jump["target"]
    scene = _scene([jump], frame_count=8, meshes=[FLOOR])
    assert [frame_change(scene, f - 1, f) for f in (3, 4, 5)] == ["static", "moving", "static"]
    results = render(scene, spp=1, size=(64, 64), temporal=True, denoise=True, frames=range(8), max_depth=3)
    left, right = (slice(20, 44), slice(6, 20)), (slice(20, 44), slice(44, 58))
    pool = results[0].color[left].mean()
    for result in results[4:]:
        assert result.color[left].mean() < 0.02 * pool and abs(result.color[right].mean() / pool - 1) < 0.1


def test_mitsubas_scene_of_a_frame_has_that_frames_lights(mi):
    """The gold of frame 4 is rendered under frame 4's lights (wgpu_rt.scene.mitsuba.to_mitsuba)."""
    from wgpu_rt.scene.mitsuba import to_mitsuba

    scene = _scene([SWEEP, FADE])
    lamp = to_mitsuba(scene, 8, 8, spp=1, max_depth=2, frame=4)["light001"]
    assert lamp["position"] == [0.0, 1.0, 0.5] and lamp["intensity"]["value"] == [0.25] * 3
    spot = to_mitsuba(scene, 8, 8, spp=1, max_depth=2, frame=4)["light000"]
    assert (spot["cutoff_angle"], spot["beam_width"]) == (30.0, 22.5)
    np.testing.assert_allclose(np.array(spot["to_world"].matrix)[:3, 3], [0, 1.5, 0], atol=1e-6)
