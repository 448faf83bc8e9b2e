"""The temporal pass against its numpy references: reprojection with disocclusion tests, clamped
blending (each clamp mode, with and without a confidence model), plain accumulation and cuts."""

import numpy as np
import pytest
from parity import check_parity

from wgpu_rt.errors import WgpuRtError
from wgpu_rt.frame.pack import DepthMaxPass, pack_confidence_input
from wgpu_rt.frame.planes import CONFIDENCE_INPUT, DENOISED, write_plane
from wgpu_rt.frame.temporal import (
    HISTORY,
    REPROJECTED,
    TEMPORAL,
    TemporalPass,
    TemporalSettings,
    accumulate_history,
    blend_history,
    frame_change,
    reproject_history,
)
from wgpu_rt.passes import DEPTH, MOTION, NORMAL, FrameBuffers
from wgpu_rt.scene.model import Camera, Scene

H, W = 20, 28


def unit(v):
    return (v / np.linalg.norm(v, axis=-1, keepdims=True)).astype(np.float32)


def moving_frame(seed):
    """A current frame plus a history that partly matches it (depth off by up to ±10 %, a few flipped
    normals, some empty texels) and sub-pixel motion reaching off-screen at the borders."""
    rng = np.random.default_rng(seed)
    color = rng.exponential(1.0, (H, W, 3)).astype(np.float32)
    depth = (4.0 + 0.02 * np.arange(W)[None, :] + 0.01 * np.arange(H)[:, None]
             + rng.uniform(0, 0.05, (H, W))).astype(np.float32)
    depth[:3, :5] = 0.0                                               # sky
    normal = unit(rng.normal(size=(H, W, 3)) + [0, 0, 3])
    motion = rng.uniform(-2.5, 2.5, (H, W, 2)).astype(np.float32)
    motion[5, 5] = [1.0, -1.0]                                        # whole-pixel shift
    history = np.concatenate([
        rng.exponential(1.0, (H, W, 3)),
        (depth * rng.uniform(0.93, 1.07, (H, W)))[..., None],
        normal * np.where(rng.uniform(size=(H, W, 1)) < 0.1, -1, 1),
        rng.integers(0, 6, (H, W, 1)),
    ], axis=-1).astype(np.float32)
    history[4, 6, 3:] = [depth[5, 5], *normal[5, 5], 2.0]           # where pixel (5, 5) came from
    return color, depth, normal, motion, history


class FixedConfidence:
    """A stand-in confidence model: records nothing, returns a preset plane; keeps the packed input."""

    def __init__(self, gpu, confidence):
        self.buffer = gpu.upload(confidence.astype(np.float32))
        self.seen_input = None

    def record(self, encoder, input_buffer, height, width):
        self.seen_input = input_buffer
        return self.buffer


def run_temporal(gpu, color, depth, normal, motion, history, change, settings=TemporalSettings(),
                 model=None):
    buffers = FrameBuffers(gpu, W, H)
    for spec, image in ((DENOISED, color), (DEPTH, depth), (NORMAL, normal), (MOTION, motion),
                        (HISTORY, history)):
        write_plane(buffers, spec, image)
    depth_max = DepthMaxPass(gpu, W, H)
    temporal = TemporalPass(gpu, W, H, DENOISED, settings, model, depth_max.result if model else None)
    encoder = gpu.device.create_command_encoder()
    depth_max.execute(encoder, buffers)
    temporal.execute(encoder, buffers, change)
    gpu.device.queue.submit([encoder.finish()])
    return buffers


def read_image(buffers, spec):
    return buffers.read(spec.name).transpose(1, 2, 0)


def test_reproject_matches_reference(gpu):
    color, depth, normal, motion, history = moving_frame(0)
    buffers = run_temporal(gpu, color, depth, normal, motion, history, "moving")
    ours = read_image(buffers, REPROJECTED)
    ref = reproject_history(history, depth, normal, motion)
    check_parity(None, lambda: ref, lambda: ours, atol=1e-5, rtol=1e-5, inputs=[], name="reproject")
    valid = ref[..., 4] > 0
    assert 0.2 < valid.mean() < 0.95          # both outcomes of the disocclusion tests occur
    np.testing.assert_allclose(ours[5, 5, :3], history[4, 6, :3], rtol=1e-6)   # exact 1-pixel shift


def test_reproject_reference_rejects_by_depth_and_normal():
    history = np.zeros((1, 2, 8), np.float32)
    history[0, :, 3] = [10.0, 10.0]
    history[0, :, 6] = [1.0, -1.0]
    history[0, :, 7] = 1.0
    history[0, :, 0] = [7.0, 9.0]
    normal = np.array([[[0, 0, 1], [0, 0, 1]]], np.float32)
    motion = np.zeros((1, 2, 2), np.float32)
    out = reproject_history(history, np.array([[10.4, 10.0]]), normal, motion)
    assert out[0, 0, 0] == 7.0 and out[0, 0, 4] == 1.0       # 4 % depth change: same surface
    assert out[0, 1, 4] == 0.0                               # flipped normal: disoccluded
    assert reproject_history(history, np.array([[10.6, 10.0]]), normal, motion)[0, 0, 4] == 0.0


@pytest.mark.parametrize("clamp", ["none", "box", "variance"])
def test_blend_matches_reference(gpu, clamp):
    settings = TemporalSettings(clamp=clamp, gamma=0.75, max_frames=4)
    color, depth, normal, motion, history = moving_frame(1)
    buffers = run_temporal(gpu, color, depth, normal, motion, history, "moving", settings)
    reprojected = reproject_history(history, depth, normal, motion, settings)
    out, new_history = blend_history(color, depth, normal, reprojected, settings=settings)
    check_parity(None, lambda: out, lambda: read_image(buffers, TEMPORAL), atol=2e-5, rtol=2e-5,
                 inputs=[], name=f"blend {clamp}")
    check_parity(None, lambda: new_history, lambda: read_image(buffers, HISTORY), atol=2e-5, rtol=2e-5,
                 inputs=[], name="history")
    assert new_history[..., 7].max() == 4                      # length capped at max_frames


@pytest.mark.parametrize("floor", [0.0, 0.3])
def test_blend_by_confidence_model(gpu, floor):
    settings = TemporalSettings(clamp="box", max_frames=50, confidence_floor=floor)
    color, depth, normal, motion, history = moving_frame(2)
    confidence = np.random.default_rng(3).uniform(0, 1, (H, W)).astype(np.float32)
    confidence[0, 0] = np.nan
    model = FixedConfidence(gpu, confidence)
    buffers = run_temporal(gpu, color, depth, normal, motion, history, "moving", settings, model)
    reprojected = reproject_history(history, depth, normal, motion, settings)
    out, _ = blend_history(color, depth, normal, reprojected, confidence, settings)
    check_parity(None, lambda: out, lambda: read_image(buffers, TEMPORAL), atol=2e-5, rtol=2e-5,
                 inputs=[], name="blend by confidence")
    untrusted = (confidence <= floor) & (reprojected[..., 4] > 0)   # at or below the floor: no history
    assert untrusted.any() == (floor > 0)
    np.testing.assert_allclose(out[untrusted], color[untrusted], atol=1e-6)
    assert model.seen_input is buffers[CONFIDENCE_INPUT.name]
    packed = buffers.read(CONFIDENCE_INPUT.name)
    expected = pack_confidence_input(color, reprojected[..., :3], depth, reprojected[..., 3])
    np.testing.assert_allclose(packed, expected, atol=1e-5, rtol=1e-5)


def test_static_camera_accumulates_to_the_mean(gpu):
    """Frames of a static view average exactly (α = 1/n) until max_frames, then α stays 1/max_frames."""
    rng = np.random.default_rng(4)
    _, depth, normal, motion, _ = moving_frame(4)
    settings = TemporalSettings(max_frames=3)
    frames = [rng.exponential(1.0, (H, W, 3)).astype(np.float32) for _ in range(4)]
    history = np.zeros((H, W, 8), np.float32)
    outputs = []
    for i, frame in enumerate(frames):
        buffers = run_temporal(gpu, frame, depth, normal, motion, history, "cut" if i == 0 else "static",
                               settings)
        ref_out, ref_history = accumulate_history(frame, depth, normal, history if i else
                                                  np.zeros_like(history), settings)
        history = read_image(buffers, HISTORY)
        outputs.append(read_image(buffers, TEMPORAL))
        np.testing.assert_allclose(outputs[-1], ref_out, rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(history, ref_history, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(outputs[2], np.mean(frames[:3], axis=0), rtol=1e-5)
    np.testing.assert_allclose(outputs[3], outputs[2] + (frames[3] - outputs[2]) / 3, rtol=1e-5)


def test_cut_discards_history(gpu):
    color, depth, normal, motion, history = moving_frame(5)
    buffers = run_temporal(gpu, color, depth, normal, motion, history, "cut")
    np.testing.assert_array_equal(read_image(buffers, TEMPORAL), color)
    assert np.all(read_image(buffers, HISTORY)[..., 7] == 1)


@pytest.mark.parametrize("poison", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("change", ["moving", "static"])
def test_non_finite_inputs_never_reach_output(gpu, poison, change):
    rng = np.random.default_rng(6)
    planes = list(moving_frame(6))
    for plane in planes[:4]:
        plane[rng.uniform(size=plane.shape) < 0.1] = poison
    buffers = run_temporal(gpu, *planes, change)
    for spec in (TEMPORAL, HISTORY):
        assert np.all(np.isfinite(buffers.read(spec.name)))


def test_frame_change_classifies_cameras():
    camera = Camera(origin=[0, 0, 5], target=[0, 0, 0])
    scene = Scene(camera=camera, meshes=[], materials={}, camera_keyframes={
        0: camera, 1: camera, 2: Camera(origin=[0.1, 0, 5], target=[0, 0, 0]),
        3: Camera(origin=[5, 0, 0], target=[0, 0, 0])})
    assert frame_change(scene, None, 0) == "cut"
    assert frame_change(scene, 0, 1) == "static"
    assert frame_change(scene, 1, 2) == "moving"
    assert frame_change(scene, 2, 3) == "cut"          # 90° swing
    assert frame_change(scene, 0, 2) == "cut"          # skipped a frame


def test_bad_clamp_names_it():
    with pytest.raises(WgpuRtError, match="'median'"):
        TemporalSettings(clamp="median")


@pytest.mark.parametrize("field, value", [("max_frames", 0), ("gamma", 0.0), ("confidence_floor", 1.0),
                                          ("confidence_floor", -0.1)])
def test_bad_temporal_settings_are_refused(field, value):
    with pytest.raises(WgpuRtError, match=field):
        TemporalSettings(**{field: value})
