"""The thin-lens camera: rays from an aperture disc that meet on the plane in focus, so that plane stays as
sharp as a pinhole sees it and everything off it blurs by the circle of confusion; a pinhole's images stay
as they were; bad lens settings refused by field. Mitsuba's agreement is in tests/test_mitsuba.py."""

import numpy as np
import pytest
from test_textures import _albedo, _scene, _texture, _tile

from wgpu_rt.errors import SceneError
from wgpu_rt.scene.model import Camera


def _tile_scene(aperture_radius=0.0, focus_distance=None):
    scene = _scene(_tile(_texture(32, 32, seed=12)))
    scene.camera.aperture_radius, scene.camera.focus_distance = aperture_radius, focus_distance or 1.0
    return scene


def test_the_plane_in_focus_stays_sharp_and_the_rest_blurs(gpu):
    """The tile 1 unit ahead, a texel a pixel: focused on it, a wide aperture sees the texture as the pinhole
    does (every ray of a pixel meets the tile at the pinhole ray's point); focused at half the distance, an
    aperture of radius 0.1 spreads each pixel's rays over a disc of radius 0.1 on the tile (1.6 px at the
    image's 16 px a unit), so the texels' contrast drops."""
    pinhole = _albedo(gpu, _tile_scene(), spp=16)
    focused = _albedo(gpu, _tile_scene(0.2, 1.0), spp=16)
    blurred = _albedo(gpu, _tile_scene(0.1, 0.5), spp=64)
    np.testing.assert_allclose(focused, pinhole, atol=2e-3)
    inner = (slice(4, -4), slice(4, -4))
    assert np.std(blurred[inner]) < 0.6 * np.std(pinhole[inner])
    assert abs(float(blurred[inner].mean() - pinhole[inner].mean())) < 0.02     # blurred, not darkened


def test_a_pinhole_keeps_its_image_bit_for_bit(gpu):
    """An aperture of 0 takes the pinhole's rays: the same as before the lens existed, whatever the focus."""
    np.testing.assert_array_equal(_albedo(gpu, _tile_scene(0.0, 0.3)), _albedo(gpu, _tile_scene(0.0, 7.0)))


def test_lens_settings_interpolate_between_keyframes():
    from wgpu_rt.scene.model import Scene

    a = Camera([0, 0, 1], [0, 0, 0], aperture_radius=0.0)
    b = Camera([0, 0, 3], [0, 0, 0], aperture_radius=0.2, focus_distance=5.0)
    scene = Scene(a, [], {}, camera_keyframes={0: a, 4: b})
    halfway = scene.camera_at(2)
    assert halfway.aperture_radius == pytest.approx(0.1) and halfway.focus_distance == pytest.approx(3.0)
    assert a.focus_distance == pytest.approx(1.0)      # the target's distance by default


@pytest.mark.parametrize("camera, message", [
    ({"aperture_radius": -0.1}, r"camera\.aperture_radius: aperture_radius must be finite and not negative"),
    ({"aperture_radius": 0.1, "focus_distance": 0}, r"camera\.focus_distance: focus_distance must be finite"),
    ({"aperture_radius": "wide"}, r"camera\.aperture_radius: expected a number"),
])
def test_bad_lens_settings_are_refused_by_field(tmp_path, camera, message):
    from wgpu_rt.scene.loader import parse_scene

    data = {"camera": {"origin": [0, 0, 3], "target": [0, 0, 0], **camera},
            "materials": {"lamp": {"emission": 1.0}}, "meshes": [{"shape": "cube", "material": "lamp"}]}
    with pytest.raises(SceneError, match=message):
        parse_scene(data, "scene.json", tmp_path)


def test_a_keyframe_that_moves_the_camera_refocuses_on_its_target(tmp_path):
    from wgpu_rt.scene.loader import parse_scene

    data = {"camera": {"origin": [0, 0, 3], "target": [0, 0, 0], "aperture_radius": 0.1, "focus_distance": 2.0,
                       "keyframes": [{"frame": 0}, {"frame": 1, "fov": 30}, {"frame": 2, "origin": [0, 0, 5]},
                                     {"frame": 3, "origin": [0, 0, 5], "focus_distance": 4.5}]},
            "materials": {"lamp": {"emission": 1.0}}, "meshes": [{"shape": "cube", "material": "lamp"}]}
    scene = parse_scene(data, "scene.json", tmp_path)
    assert [scene.camera_at(f).focus_distance for f in range(4)] == pytest.approx([2.0, 2.0, 5.0, 4.5])
    assert all(scene.camera_at(f).aperture_radius == pytest.approx(0.1) for f in range(4))


def test_the_aux_pass_takes_more_samples_through_a_lens(gpu, monkeypatch):
    """Out of focus a pixel's albedo mixes what the aperture's points see: AUX_LENS_FACTOR times the samples
    bring the aux pass's albedo closer to a converged one than the pinhole's count does."""
    from wgpu_rt.trace import trace_pass

    scene = _tile_scene(0.1, 0.5)
    converged = _albedo(gpu, scene, spp=1, aux_samples=256)
    near = np.abs(_albedo(gpu, scene, spp=1, aux_samples=4) - converged).mean()
    monkeypatch.setattr(trace_pass, "AUX_LENS_FACTOR", 1)
    far = np.abs(_albedo(gpu, scene, spp=1, aux_samples=4) - converged).mean()
    assert near < 0.6 * far, (near, far)


def test_through_a_lens_the_aux_pass_also_averages_normals_and_depth(gpu):
    """A tile half a unit nearer than a tilted one, out of focus: at 1 spp the tracer's normal and depth planes
    hold one sample's first hit (one tile's or the other's), the aux pass's the means over its samples, which
    blend the two across the blurred step between them."""
    import copy

    from wgpu_rt.accel.geometry import GeometryBuffers
    from wgpu_rt.passes import FrameBuffers
    from wgpu_rt.scene.transforms import rotate
    from wgpu_rt.trace import SampleSchedule, TracePass

    near = _tile(_texture(seed=13))
    far = copy.copy(near)
    far.name, far.transform = "far", np.asarray(rotate([0, 1, 0], 20), np.float32)
    near.transform = np.diag([0.5, 2, 1, 1]).astype(np.float32)
    near.transform[:3, 3] = [-0.5, 0, 0.5]           # the left half, half a unit nearer
    scene = _scene(near, far)
    scene.camera.aperture_radius, scene.camera.focus_distance = 0.2, 0.2

    def planes(aux: bool):
        trace = TracePass(gpu, scene, GeometryBuffers.build(scene), 32, 32, max_depth=2, seed=3)
        buffers = FrameBuffers(gpu, 32, 32)
        encoder = gpu.device.create_command_encoder()
        trace.clear(encoder, buffers)
        trace.execute(encoder, buffers, SampleSchedule(1))
        if aux:
            trace.execute_aux(encoder, buffers, 16)
        gpu.device.queue.submit([encoder.finish()])
        return buffers.read("normal")[0, :, 12:20], buffers.read("depth").reshape(32, 32)[:, 12:20]

    (normal_x, depth), (averaged_x, averaged_depth) = planes(False), planes(True)
    sin = np.sin(np.radians(20))                       # the tilted tile's normal's x
    assert np.all(np.isclose(np.abs(normal_x), 0, atol=1e-5) | np.isclose(np.abs(normal_x), sin, atol=1e-3))
    assert np.mean((np.abs(averaged_x) > 0.1 * sin) & (np.abs(averaged_x) < 0.9 * sin)) > 0.3
    one_hit = np.isclose(depth, 0.5, atol=0.01) | (depth > 0.6) | (depth == 0)   # near, tilted, or a miss
    assert np.all(one_hit) and np.mean(np.isclose(depth, 0.5, atol=0.01)) > 0.2
    assert np.mean((averaged_depth > 0.55) & (averaged_depth < 0.9)) > 0.3        # means between the two
