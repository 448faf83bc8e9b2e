"""Spot lights (Mitsuba's `spot`): full intensity within the beam width of the axis, falling linearly in
angle to nothing at the cutoff. The direct light on a floor against the closed form; scene-file entries and
their errors; Mitsuba's agreement is in tests/test_mitsuba.py."""

import numpy as np
import pytest
from scene_scores import camera_rays

from wgpu_rt.errors import SceneError
from wgpu_rt.renderer import render
from wgpu_rt.scene.loader import parse_scene
from wgpu_rt.scene.model import Camera, Material, Mesh, Scene, SpotLight
from wgpu_rt.scene.primitives import rectangle
from wgpu_rt.scene.transforms import compose, rotate, scale

SIZE = 48
FLOOR = 0.7


def test_falloff_is_full_in_the_beam_linear_to_the_cutoff_and_zero_beyond():
    spot = SpotLight(np.zeros(3), np.ones(3), direction=[0, 0, 2], cutoff_angle=30, beam_width=10)
    angles = np.radians([0, 10, 20, 29.9, 30.1, 90, 180])
    directions = np.stack([np.sin(angles), np.zeros_like(angles), np.cos(angles)], -1)
    np.testing.assert_allclose(spot.falloff(directions), [1, 1, 0.5, 0.005, 0, 0, 0], atol=1e-6)
    assert SpotLight(np.zeros(3), np.ones(3)).beam_width == 15.0      # Mitsuba's default: ¾ of 20°


def test_direct_light_on_a_floor_is_the_closed_form(gpu):
    """A white floor under a tilted spot, seen from straight above, direct light only: each pixel's radiance
    is ρ/π · I · falloff · cos θ / d² at the floor point its centre sees."""
    spot = SpotLight(np.float32([0.3, 1.5, -0.2]), np.float32([2.0, 1.5, 1.0]), direction=[0.2, -1, 0.1],
                     cutoff_angle=40, beam_width=25)
    floor = Mesh("floor", *rectangle()[:2], "floor", transform=compose(rotate([1, 0, 0], -90), scale(2)))
    camera = Camera([0, 3, 0], [0, 0, 0], up=[0, 0, -1], fov=60)
    scene = Scene(camera, [floor], {"floor": Material(reflectance=FLOOR)}, [spot], name="spot floor")
    ours = render(scene, spp=16, size=(SIZE, SIZE), max_depth=2, aovs=()).color

    rays = camera_rays(camera, SIZE).astype(np.float64)
    points = camera.origin + rays * (-camera.origin[1] / rays[..., 1:2])          # on the plane y = 0
    offset = points - spot.position
    distance = np.linalg.norm(offset, axis=-1)
    out = offset / distance[..., None]
    cos_floor = -out[..., 1]
    expected = (FLOOR / np.pi * spot.intensity * (spot.falloff(out.reshape(-1, 3)).reshape(SIZE, SIZE)
                                                  * cos_floor / distance ** 2)[..., None])
    lit = expected[..., 0] > 0.05 * expected[..., 0].max()
    assert lit.mean() > 0.2 and (~lit).mean() > 0.2          # the cone's edge crosses the view
    relative = np.abs(ours[lit] - expected[lit]) / expected[lit]
    assert np.median(relative) < 0.01 and np.percentile(relative, 90) < 0.05, np.percentile(relative, [50, 90])
    dark = expected[..., 0] == 0
    assert np.all(ours[dark] < 0.02 * expected.max())        # beyond the cutoff, only pixels straddling it


def _spot_entry(**keys):
    return {"camera": {"origin": [0, 0, 3], "target": [0, 0, 0]}, "materials": {"white": {}},
            "meshes": [{"shape": "rectangle", "material": "white"}],
            "lights": [{"type": "spot", "position": [0, 0, 2], "intensity": 3, **keys}]}


def test_a_spot_entry_aims_by_direction_or_target(tmp_path):
    by_target = parse_scene(_spot_entry(target=[0, 0, 0], cutoff_angle=40), "scene.json", tmp_path).lights[0]
    by_direction = parse_scene(_spot_entry(direction=[0, 0, -5], beam_width=5), "scene.json", tmp_path).lights[0]
    np.testing.assert_allclose(by_target.direction, [0, 0, -1])
    np.testing.assert_allclose(by_direction.direction, [0, 0, -1])
    assert (by_target.cutoff_angle, by_target.beam_width) == (40, 30)
    assert (by_direction.cutoff_angle, by_direction.beam_width) == (20, 5)


@pytest.mark.parametrize("keys, message", [
    ({}, r"lights\[0\]: give exactly one of 'direction'"),
    ({"direction": [0, 0, -1], "target": [0, 0, 0]}, r"lights\[0\]: give exactly one of 'direction'"),
    ({"direction": [0, 0, 0]}, r"lights\[0\]\.direction: must not be zero"),
    ({"target": [0, 0, 2]}, r"lights\[0\]\.target: must differ from the position"),
    ({"target": [0, 0, 0], "cutoff_angle": 120}, r"lights\[0\]\.cutoff_angle: cutoff_angle must be in \(0, 90\]"),
    ({"target": [0, 0, 0], "beam_width": 25}, r"lights\[0\]\.beam_width: beam_width must be in \[0, cutoff_angle\)"),
])
def test_bad_spot_entries_are_refused_by_field(tmp_path, keys, message):
    with pytest.raises(SceneError, match=message):
        parse_scene(_spot_entry(**keys), "scene.json", tmp_path)
