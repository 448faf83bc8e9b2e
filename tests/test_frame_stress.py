"""Numerical stress of the whole frame pipeline with real WgslModels (the seed networks, in fp16 and
fp32): HDR values up to the fp16 maximum 65504 (and far beyond) and NaN/±Inf injected into each input
plane must never reach the display output or the temporal history (which would carry them forward).

The tracer is replaced by a stand-in that "traces" by copying fixed planes, so every other stage —
depth max, pack, error predictor + sample map, denoiser, unpack, reprojection, confidence network,
blend, tone-map — runs exactly as in a rendered frame."""

import numpy as np
import pytest

from wgpu_rt.frame.adaptive import AdaptiveSettings
from wgpu_rt.frame.denoise import load_model
from wgpu_rt.frame.pipeline import FramePipeline
from wgpu_rt.renderer import render
from wgpu_rt.frame.planes import to_planar
from wgpu_rt.frame.temporal import HISTORY, TemporalSettings
from wgpu_rt.passes import ALBEDO, DEPTH, MOTION, NORMAL, NUMPY_DTYPE, RADIANCE
from wgpu_rt.scene.builtin import builtin_scene

W, H = 32, 24
FP16_MAX = 65504.0


@pytest.fixture(params=["fp16", "fp32"])
def precision(request, gpu):
    if request.param == "fp16" and not gpu.has_f16:
        pytest.skip(f"{gpu.label} has no shader-f16")
    return request.param


class RecordedTrace:
    """Stands in for a TracePass: each ``execute`` copies planes uploaded once, before the frame."""

    def __init__(self, gpu, planes: dict):
        self.sources = {spec: gpu.upload(to_planar(image).astype(NUMPY_DTYPE[spec.dtype]))
                        for spec, image in planes.items()}

    def clear(self, encoder, buffers) -> None:
        pass

    def execute(self, encoder, buffers, schedule=None) -> None:
        for spec, source in self.sources.items():
            encoder.copy_buffer_to_buffer(source, 0, buffers.get(spec), 0, spec.nbytes(W, H))


def hdr_planes(seed=0):
    """Plausible G-buffers with radiance spanning 0 … 65504 (a ramp over the bottom rows) and a few
    pixels far above the fp16 range."""
    rng = np.random.default_rng(seed)
    radiance = rng.exponential(2.0, (H, W, 3)).astype(np.float32)
    radiance[-4:] = np.geomspace(1e-3, FP16_MAX, 4 * W * 3).reshape(4, W, 3)
    radiance[0, :3] = [[FP16_MAX] * 3, [1e6] * 3, [3.0e38] * 3]
    normal = rng.normal(size=(H, W, 3)) + [0, 0, 2]
    return {RADIANCE: radiance,
            ALBEDO: rng.uniform(0, 1, (H, W, 3)),
            NORMAL: normal / np.linalg.norm(normal, axis=-1, keepdims=True),
            DEPTH: rng.uniform(1, 5, (H, W)),
            MOTION: rng.uniform(-1.5, 1.5, (H, W, 2))}


def poisoned(planes, spec, value):
    planes = {k: np.array(v, np.float32) for k, v in planes.items()}
    image = planes[spec].reshape(H, W, -1)
    image[5, 7] = value
    image[10, :] = value                    # a whole row
    image[15:18, 20:23, 0] = value          # one channel of a block
    return planes


def run_frames(gpu, scene, models, precision, planes_per_frame):
    """Frames 0, 1, … of ``scene`` (so temporal takes the cut, then the reprojection path) with the
    given planes; returns the f32 linear display images and the final history."""
    networks = {name: load_model(name, precision, models) for name in ("denoiser", "error_predictor", "confidence")}
    traces = [RecordedTrace(gpu, planes) for planes in planes_per_frame]
    pipeline = FramePipeline(gpu, W, H, lambda frame, _: traces[frame], denoiser=networks["denoiser"],
                             adaptive=AdaptiveSettings(budget=2.0), error_predictor=networks["error_predictor"],
                             temporal=TemporalSettings(), confidence=networks["confidence"], operator=None)
    images = [pipeline.render(scene, frame).color for frame in range(len(traces))]
    return images, pipeline.buffers.read(HISTORY.name)


def assert_finite(images, history):
    for i, image in enumerate(images):
        bad = np.count_nonzero(~np.isfinite(image))
        assert bad == 0, f"frame {i}: {bad} non-finite output values"
        assert image[..., :3].min() >= 0
    assert np.all(np.isfinite(history)), f"{np.count_nonzero(~np.isfinite(history))} non-finite history values"


def test_hdr_up_to_fp16_max_stays_finite(gpu, moving, seed_models, precision):
    images, history = run_frames(gpu, moving, seed_models, precision, [hdr_planes(0), hdr_planes(1)])
    assert_finite(images, history)


@pytest.mark.parametrize("poison", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("spec", [RADIANCE, ALBEDO, NORMAL, DEPTH, MOTION], ids=lambda s: s.name)
def test_non_finite_input_never_reaches_output(gpu, moving, seed_models, spec, poison):
    planes = [poisoned(hdr_planes(0), spec, poison), poisoned(hdr_planes(1), spec, poison)]
    images, history = run_frames(gpu, moving, seed_models, "fp16" if gpu.has_f16 else "fp32", planes)
    assert_finite(images, history)


def test_sun_room_through_fp16_networks(gpu, seed_models, precision):
    """sun-room's sun (radiance 5·10⁴, near the fp16 maximum) seen directly and through a window, with
    every network in the chosen precision."""
    frames = render(builtin_scene("sun-room"), denoise=True, adaptive=3.0, temporal=True, frames=[0, 1],
                    size=(W, H), max_depth=4, precision=precision, models_dir=seed_models, ctx=gpu)
    assert_finite([f.color for f in frames], np.zeros(1))
