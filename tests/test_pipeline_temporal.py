"""The fused pipeline on animated frames: the ``moving`` scene's camera and box move every frame, so
frames after the first take the reprojection path. Checked end to end against the numpy references
(reprojection, confidence packing, blending) fed with the planes the pipeline itself traced, with a
real WgslModel of the seed Confidence Predictor whose output is recomputed by onnxruntime."""

import numpy as np
import pytest

from wgpu_rt.frame.pack import pack_confidence_input
from wgpu_rt.frame.pipeline import FramePipeline
from wgpu_rt.frame.planes import CONFIDENCE_INPUT
from wgpu_rt.frame.temporal import (
    HISTORY,
    REPROJECTED,
    TEMPORAL,
    TemporalSettings,
    blend_history,
    frame_change,
    reproject_history,
)
from wgpu_rt.passes import DEPTH, MOTION, NORMAL, RADIANCE
from wgpu_rt.renderer import render

W, H = 32, 24


def hwc(buffers, spec):
    return buffers.read(spec.name).transpose(1, 2, 0)


def traced_pipeline(gpu, scene, **settings):
    from wgpu_rt.accel.geometry import GeometryBuffers
    from wgpu_rt.trace.trace_pass import TracePass

    def trace_factory(frame, seed_frame):
        return TracePass(gpu, scene, GeometryBuffers.build(scene, frame), W, H, frame=frame, max_depth=3,
                         seed=seed_frame)

    return FramePipeline(gpu, W, H, trace_factory, operator=None, **settings)


def onnx_confidence(path, packed):
    import onnxruntime

    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    return session.run(None, {session.get_inputs()[0].name: packed[None]})[0][0, 0]


@pytest.mark.parametrize("use_model", [False, True])
def test_moving_frame_matches_references(gpu, moving, seed_models, use_model):
    """Frame 1 of ``moving`` after frame 0: reproject → (confidence network) → blend, equal to the numpy
    references applied to the traced planes and frame 0's history."""
    from wgpu_rt.nn import WgslModel

    settings = TemporalSettings(clamp="box")
    model = WgslModel(seed_models / "confidence.onnx", "fp32", ctx=gpu) if use_model else None
    pipeline = traced_pipeline(gpu, moving, temporal=settings, confidence=model)
    pipeline.render(moving, 0)
    history = hwc(pipeline.buffers, HISTORY)
    assert frame_change(moving, 0, 1) == "moving"
    image = pipeline.render(moving, 1).color
    color, depth, normal, motion = (hwc(pipeline.buffers, spec) for spec in (RADIANCE, DEPTH, NORMAL, MOTION))
    assert np.abs(motion).max() > 0.1                                 # the camera really moved
    reprojected = reproject_history(history, depth, normal, motion, settings)
    np.testing.assert_allclose(hwc(pipeline.buffers, REPROJECTED), reprojected, rtol=1e-4, atol=1e-4)
    valid = reprojected[..., 4] > 0
    assert 0.5 < valid.mean() < 1.0                                   # history kept, some disoccluded
    confidence = None
    if use_model:
        packed = pack_confidence_input(color, reprojected[..., :3], depth, reprojected[..., 3])
        np.testing.assert_allclose(pipeline.buffers.read(CONFIDENCE_INPUT.name), packed, rtol=1e-4, atol=1e-4)
        confidence = onnx_confidence(seed_models / "confidence.onnx", packed)
    expected, _ = blend_history(color, depth, normal, reprojected, confidence, settings)
    np.testing.assert_allclose(hwc(pipeline.buffers, TEMPORAL), expected, rtol=1e-3, atol=1e-4)
    np.testing.assert_allclose(image, expected, rtol=1e-3, atol=1e-4)
    without_history, _ = blend_history(color, depth, normal, np.zeros_like(reprojected), None, settings)
    assert np.abs(image - without_history)[valid].max() > 1e-3   # history was really used


def test_render_moving_with_every_seed_model(gpu, moving, seed_models):
    """render loads all three networks from a folder and runs denoise + adaptive + temporal with
    the confidence network over animated frames: finite images of the right shape, and the adaptive
    budget and motion both in effect."""
    frames = render(moving, denoise=True, adaptive=2.0, temporal=True, frames=range(3), size=(W, H),
                    max_depth=3, models_dir=seed_models, ctx=gpu, aovs=("spp",))
    assert [f.frame for f in frames] == [0, 1, 2]
    for frame in frames:
        assert frame.color.shape == (H, W, 3) and np.all(np.isfinite(frame.color))
        assert frame.color.min() >= 0
        assert frame.aovs["spp"].mean() == pytest.approx(2.0, abs=0.01)
    assert np.abs(frames[2].color - frames[1].color).max() > 0
