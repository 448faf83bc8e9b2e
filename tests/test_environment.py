"""Environment maps: a latitude-longitude image as the sky (Mitsuba's envmap convention and filtering), seen
directly and lighting the scene through the background's next-event estimate; scene files' `environment`; bad
images refused by name. Mitsuba's agreement is in tests/test_mitsuba.py."""

import numpy as np
import pytest
from scene_scores import camera_rays

from wgpu_rt.errors import SceneError
from wgpu_rt.renderer import render
from wgpu_rt.scene.model import (Camera, Material, Mesh, Scene, environment_uv, linear_from_srgb8,
                                  sample_environment)
from wgpu_rt.scene.primitives import rectangle
from wgpu_rt.scene.transforms import compose, scale, translate

SIZE = 32


def smooth_sky(height=24, width=48) -> np.ndarray:
    """Smooth in both directions, so a pixel's mean is its centre's value, and different in every direction."""
    theta = np.pi * np.arange(height) / (height - 1)
    phi = 2 * np.pi * (np.arange(width) + 0.5) / width
    t, p = np.meshgrid(theta, phi, indexing="ij")
    return np.stack([1 + 0.5 * np.cos(t), 1 + 0.4 * np.sin(p) * np.sin(t), 0.6 + 0.3 * np.cos(2 * p) * np.sin(t)],
                    -1).astype(np.float32)


def sky_scene(environment, camera) -> Scene:
    """Nothing in view but the sky: one small tile far behind the camera."""
    tile = Mesh("tile", *rectangle()[:2], "grey", transform=compose(translate([0, 0, 1e3]), scale(0.01)))
    return Scene(camera, [tile], {"grey": Material()}, background=np.ones(3, np.float32), environment=environment,
                 name="sky")


def test_texel_centres_and_the_seam():
    sky = smooth_sky(25, 48)                                         # row 12 on the horizon
    height, width = sky.shape[:2]
    rows, columns = np.meshgrid(np.arange(height), np.arange(width), indexing="ij")
    theta, phi = np.pi * rows / (height - 1), 2 * np.pi * (columns + 0.5) / width
    directions = np.stack([np.sin(phi) * np.sin(theta), np.cos(theta), -np.cos(phi) * np.sin(theta)], -1).reshape(-1, 3)
    np.testing.assert_allclose(environment_uv(directions)[:, 1], (rows / (height - 1)).ravel(), atol=1e-9)
    np.testing.assert_allclose(sample_environment(sky, directions), sky.reshape(-1, 3), atol=1e-5)
    seam = np.array([[-1e-7, 0, -1.0], [1e-7, 0, -1.0]])            # u just below and above 0 (straight along −z)
    left, right = sample_environment(sky, seam)
    np.testing.assert_allclose(left, right, atol=1e-5)
    np.testing.assert_allclose(left, 0.5 * (sky[height // 2, 0] + sky[height // 2, -1]), atol=0.02)


@pytest.mark.parametrize("target, rotation", [([0, 0, -1], 0), ([1, 0.5, 0], 0), ([0, 1, 0.01], 0), ([1, 0.5, 0], 70)])
def test_the_sky_seen_directly_is_the_map(gpu, target, rotation):
    """Each pixel's radiance is the map along its centre's direction (horizon, sideways, the zenith), turned
    about +y by the scene's rotation (the direction turned back into the map's frame)."""
    camera = Camera([0, 0, 0], target, up=[0, 1, 0] if abs(target[1]) < 0.9 else [0, 0, -1], fov=60)
    sky = smooth_sky()
    scene = sky_scene(sky, camera)
    scene.environment_rotation = rotation
    ours = render(scene, spp=16, size=(SIZE, SIZE), max_depth=1, aovs=()).color
    rays = camera_rays(camera, SIZE)
    c, s = np.cos(np.radians(rotation)), np.sin(np.radians(rotation))
    in_map = rays @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])                # Rᵀ·d for each row d
    expected = sample_environment(sky, in_map.reshape(-1, 3)).reshape(SIZE, SIZE, 3)
    relative = np.abs(ours - expected) / expected
    assert np.median(relative) < 0.005 and relative.max() < 0.05, (np.median(relative), relative.max())


def test_a_constant_map_lights_as_the_constant_background(gpu, monkeypatch):
    """A constant map of 1 times a background of 0.5 lights the Cornell box as a constant background of 0.5:
    to rounding when its directions are drawn uniformly as a constant sky's are, and within the noise when
    drawn by the map's cells (a different pdf, the same expectation)."""
    from wgpu_rt.scene import load_scene
    from wgpu_rt.trace import scene_data, trace_pass

    constant = load_scene("cornell")
    constant.background = np.full(3, 0.5, np.float32)
    mapped = load_scene("cornell")
    mapped.background, mapped.environment = np.full(3, 0.5, np.float32), np.ones((6, 8, 3), np.float32)
    options = dict(spp=64, size=(24, 24), max_depth=4, aovs=())
    a = render(constant, **options).color
    drawn = render(mapped, **options).color
    assert abs(drawn.mean() / a.mean() - 1) < 0.01
    monkeypatch.setattr(trace_pass, "pack_environment", lambda image: scene_data.pack_environment(image, False))
    np.testing.assert_allclose(render(mapped, **options).color, a, rtol=1e-4, atol=1e-5)


def test_a_small_sun_is_found_by_sampling_the_map(gpu, monkeypatch):
    """A floor under a dim sky with a sun of 1/300 of the sphere's cells: drawing directions by the map's
    cells leaves a fraction of the error that uniform directions leave, against a 4096-spp render."""
    from wgpu_rt.trace import scene_data, trace_pass

    sky = np.full((32, 64, 3), 0.05, np.float32)
    sky[8:10, 20:23] = 400.0
    floor = Mesh("floor", *rectangle()[:2], "white", transform=np.float32([[3, 0, 0, 0], [0, 0, 3, 0],
                                                                               [0, -3, 0, 0], [0, 0, 0, 1]]))
    scene = Scene(Camera([0, 2, 3], [0, 0, 0], fov=60), [floor], {"white": Material(reflectance=0.8)},
                  background=np.ones(3, np.float32), environment=sky, name="sun floor")
    options = dict(size=(24, 24), max_depth=2, aovs=())
    reference = render(scene, spp=4096, **options).color
    drawn = render(scene, spp=4, **options).color
    monkeypatch.setattr(trace_pass, "pack_environment", lambda image: scene_data.pack_environment(image, False))
    uniform = render(scene, spp=4, **options).color
    error = lambda image: float(np.mean((image - reference) ** 2))  # noqa: E731
    assert error(drawn) < 0.1 * error(uniform), (error(drawn), error(uniform))


def test_the_background_mean_weighs_rows_by_their_solid_angle():
    sky = np.zeros((5, 4, 3), np.float32)
    sky[2] = 1.0                                                     # the horizon row alone
    scene = sky_scene(sky, Camera([0, 0, 0], [0, 0, -1]))
    weights = np.sin(np.pi * np.arange(5) / 4)
    np.testing.assert_allclose(scene.background_mean(), weights[2] / weights.sum(), rtol=1e-6)


def _scene_file(tmp_path, **top):
    from wgpu_rt.scene.loader import parse_scene

    data = {"camera": {"origin": [0, 0, 3], "target": [0, 0, 0]}, "materials": {"white": {}},
            "meshes": [{"shape": "rectangle", "material": "white"}], **top}
    return parse_scene(data, "scene.json", tmp_path)


def test_a_scene_file_reads_an_exr_or_an_image(tmp_path):
    from PIL import Image

    from wgpu_rt.io import write_exr

    sky = smooth_sky(6, 8)
    write_exr(tmp_path / "sky.exr", sky)
    scene = _scene_file(tmp_path, environment="sky.exr")
    np.testing.assert_allclose(scene.environment, sky)
    np.testing.assert_array_equal(scene.background, 1.0)             # the map as it is
    assert _scene_file(tmp_path, environment="sky.exr", background=0.25).background.tolist() == [0.25] * 3
    assert _scene_file(tmp_path, environment="sky.exr", environment_rotate=-30).environment_rotation == -30
    with pytest.raises(SceneError, match="environment_rotate: turns an environment map: give 'environment' too"):
        _scene_file(tmp_path, environment_rotate=30)
    Image.fromarray(np.full((4, 6, 3), 188, np.uint8)).save(tmp_path / "sky.png")
    np.testing.assert_allclose(_scene_file(tmp_path, environment="sky.png").environment,
                               linear_from_srgb8(np.uint8([188]))[0], rtol=1e-6)   # decoded from sRGB


@pytest.mark.parametrize("make, message", [
    (lambda path: None, r"environment: .*missing\.exr: no such file"),
    (lambda path: path.write_bytes(b"no exr"), r"environment: .*missing\.exr: not a readable OpenEXR file"),
    (lambda path: _write(path, np.full((6, 8, 3), -1, np.float32)), "6 pixels are negative|48 pixels are negative"),
    (lambda path: _write(path, np.full((2, 8, 3), 1, np.float32)), r"at least 2 pixels wide and 3 high"),
])
def test_bad_environment_maps_are_refused_by_field(tmp_path, make, message):
    make(tmp_path / "missing.exr")
    with pytest.raises(SceneError, match=message):
        _scene_file(tmp_path, environment="missing.exr")


def _write(path, image):
    from wgpu_rt.io import write_exr

    write_exr(path, image)


@pytest.mark.parametrize("image", [np.ones((2, 8, 3), np.float32), np.ones((6, 8), np.float32),
                                   np.full((6, 8, 3), np.nan, np.float32)])
def test_a_bad_map_given_in_python_is_refused_before_any_work(gpu, image):
    scene = sky_scene(image, Camera([0, 0, 0], [0, 0, -1]))
    with pytest.raises(SceneError, match="scene 'sky': environment map: "):
        render(scene, spp=1, size=(8, 8))
