"""The fused frame: trace → pack → denoiser → unpack → temporal → tone-map in one command encoder per
frame, with exactly one readback (the display image; per-stage timestamps ride in the same buffer).

Networks are objects with ``record(encoder, input_buffer, height, width) -> output_buffer`` (the NN
engine's ``wgpu_rt.nn.WgslModel``); ``render_frames`` loads them from ``models/`` by default.
Stage timings come from timestamp queries when the adapter has them: an empty compute pass with a
timestamp write marks each stage boundary, so stages recorded by other packages are timed too.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np
import wgpu

from ..errors import ModelError
from ..passes import RADIANCE, SPP, FrameBuffers
from .adaptive import (
    HALF_RADIANCE,
    HEAT,
    SAMPLE_ERROR,
    AdaptiveSettings,
    ExtraSamplesPass,
    HalfBufferErrorPass,
)
from .pack import DepthMaxPass, PackDenoiserPass, PackErrorPass
from .planes import DENOISED, DENOISER_INPUT, ERROR_INPUT
from .temporal import TEMPORAL, TemporalPass, TemporalSettings, frame_change
from .tonemap import TonemapPass
from .unpack import UnpackPass

MODEL_FILES = {"denoiser": "denoiser.onnx", "error_predictor": "error_predictor.onnx",
               "confidence": "confidence.onnx"}


@dataclass
class RenderedFrame:
    frame: int
    image: np.ndarray                                   # (H, W, 4) uint8, or float32 for f32 output
    stage_ms: dict[str, float] = field(default_factory=dict)   # empty without timestamp queries


class StageTimer:
    """Timestamp marks between stages, resolved into the tail of the frame's readback buffer."""

    def __init__(self, ctx, capacity: int = 16):
        self.ctx, self.capacity = ctx, capacity
        self.query_set = ctx.device.create_query_set(type="timestamp", count=capacity)
        self.resolved = ctx.device.create_buffer(
            size=8 * capacity, usage=wgpu.BufferUsage.QUERY_RESOLVE | wgpu.BufferUsage.COPY_SRC)
        self.names: list[str] = []

    def start(self) -> None:
        self.names = []

    def mark(self, encoder, name: str) -> None:
        """The end of stage ``name`` (the first mark is the frame's start)."""
        if len(self.names) == self.capacity:
            raise ValueError(f"more than {self.capacity} timestamp marks in one frame")
        compute_pass = encoder.begin_compute_pass(
            label=f"mark {name}", timestamp_writes={"query_set": self.query_set,
                                                    "beginning_of_pass_write_index": len(self.names)})
        compute_pass.end()
        self.names.append(name)

    def resolve(self, encoder, destination, offset: int) -> None:
        encoder.resolve_query_set(self.query_set, 0, len(self.names), self.resolved, 0)
        encoder.copy_buffer_to_buffer(self.resolved, 0, destination, offset, 8 * len(self.names))

    def stage_ms(self, raw: bytes) -> dict[str, float]:
        ticks = np.frombuffer(raw, np.uint64, count=len(self.names)).astype(np.float64)
        return {name: (ticks[i] - ticks[i - 1]) / 1e6 for i, name in enumerate(self.names) if i}


class FramePipeline:
    """Everything between a scene and its display frames, for one size and one set of settings.

    ``trace_factory(frame, seed_frame)`` returns the tracer pass for that frame (a
    ``wgpu_rt.trace.TracePass``: ``clear``, ``execute`` and a ``schedule`` of samples / per-pixel
    ``sample_counts`` / offset), its samples seeded as ``seed_frame``'s: the frame itself, or under a
    converging static view the first frame of the run, so the accumulated samples are one unbroken
    stratified sequence (at 8 spp on cornell, 96², re-seeding every frame left the mean 1.7 dB PSNR
    behind a brute-force 8-spp render: independent 1-spp sets lose the Sobol prefix's stratification).
    """

    def __init__(self, ctx, width: int, height: int, trace_factory, *, denoiser=None,
                 adaptive: AdaptiveSettings | None = None, error_model=None,
                 temporal: TemporalSettings | None = None, confidence_model=None,
                 operator: str = "aces", exposure: float = 0.0, srgb: bool = True,
                 output: str = "rgba8", timings: bool | None = None):
        if adaptive is not None and adaptive.sampler == "heat" and error_model is None:
            raise ModelError("the heat adaptive sampler needs an error predictor model")
        self.ctx, self.width, self.height = ctx, width, height
        self.trace_factory, self.denoiser, self.error_model = trace_factory, denoiser, error_model
        self.adaptive = adaptive
        self.buffers = FrameBuffers(ctx, width, height)
        self.depth_max = DepthMaxPass(ctx, width, height)
        color = RADIANCE
        if denoiser is not None:
            self.pack = PackDenoiserPass(ctx, width, height, self.depth_max.result)
            self.unpack = UnpackPass(ctx, width, height)
            color = DENOISED
        self.temporal = None
        if temporal is not None:
            self.temporal = TemporalPass(ctx, width, height, color, temporal, confidence_model,
                                         self.depth_max.result)
            color = TEMPORAL
        if adaptive is not None:
            source = SAMPLE_ERROR if adaptive.sampler == "variance" else HEAT
            self.extra_samples = ExtraSamplesPass(ctx, width, height, adaptive, source)
            self.pack_error = PackErrorPass(ctx, width, height)
            self.half_buffer_error = HalfBufferErrorPass(ctx, width, height)
        self.tonemap = TonemapPass(ctx, width, height, color, operator, exposure, srgb, output)
        display_bytes = self.tonemap.display.nbytes(width, height)
        self.timer = StageTimer(ctx) if (ctx.has_timestamps if timings is None else timings) else None
        self.readback = ctx.device.create_buffer(
            size=display_bytes + (8 * self.timer.capacity if self.timer else 0),
            usage=wgpu.BufferUsage.COPY_DST | wgpu.BufferUsage.COPY_SRC)
        self.display_bytes = display_bytes
        self.previous_frame: int | None = None
        self.seed_frame = 0

    def _mark(self, encoder, name: str) -> None:
        if self.timer:
            self.timer.mark(encoder, name)

    def _trace(self, encoder, trace, keep_samples: bool) -> None:
        """Record this frame's samples; with ``keep_samples`` they join the previous frames' in the planes
        (the tracer numbers them after each pixel's spp, so the planes stay unbiased running means)."""
        from ..trace.trace_pass import SampleSchedule

        buffers, adaptive = self.buffers, self.adaptive
        if not keep_samples:
            trace.clear(encoder, buffers)
        trace.schedule = SampleSchedule(samples=1)
        trace.execute(encoder, buffers)
        if adaptive is None:
            self._mark(encoder, "trace")
            return
        if adaptive.sampler == "variance":
            encoder.copy_buffer_to_buffer(buffers.get(RADIANCE), 0, buffers.get(HALF_RADIANCE), 0,
                                          RADIANCE.nbytes(self.width, self.height))
            trace.schedule = SampleSchedule(samples=1)   # numbered after the probe's first (spp = 1)
            trace.execute(encoder, buffers)
            self._mark(encoder, "probe")
            self.half_buffer_error.execute(encoder, buffers)
        else:
            self._mark(encoder, "probe")
            if adaptive.sampler == "heat":
                self.pack_error.execute(encoder, buffers)
                heat = self.error_model.record(encoder, buffers.get(ERROR_INPUT), self.height, self.width)
                encoder.copy_buffer_to_buffer(heat, 0, buffers.get(HEAT), 0, HEAT.nbytes(self.width, self.height))
        self.extra_samples.execute(encoder, buffers)
        self._mark(encoder, "sample map")
        # No sample_offset: the tracer already numbers these after the probe's (each pixel's spp), so
        # probe and targeted samples are one unbroken prefix of the pixel's sequence, as brute force is.
        trace.schedule = SampleSchedule(samples=adaptive.max_extra,
                                        sample_counts=buffers.get(self.extra_samples.outputs[0]))
        trace.execute(encoder, buffers)
        self._mark(encoder, "targeted trace")

    def render(self, scene, frame: int) -> RenderedFrame:
        """Record, submit and read back one frame."""
        ctx, buffers = self.ctx, self.buffers
        # Temporal mode under a static camera and scene converges in the tracer: the frame adds its
        # samples to the running mean, which is denoised and then replaces the temporal history
        # (averaging denoised 1-spp frames would keep the denoiser's bias). Any change or cut starts
        # again from zero samples.
        change = frame_change(scene, self.previous_frame, frame) if self.temporal is not None else "cut"
        converging = change == "static"
        if not converging:
            self.seed_frame = frame
        trace = self.trace_factory(frame, self.seed_frame)
        encoder = ctx.device.create_command_encoder(label=f"frame {frame}")
        if self.timer:
            self.timer.start()
        self._mark(encoder, "start")
        self._trace(encoder, trace, keep_samples=converging)
        self.depth_max.execute(encoder, buffers)
        if self.denoiser is not None:
            self.pack.execute(encoder, buffers)
            self._mark(encoder, "pack")
            self.unpack.source = self.denoiser.record(encoder, buffers.get(DENOISER_INPUT), self.height,
                                                      self.width)
            self._mark(encoder, "denoise")
            self.unpack.execute(encoder, buffers)
        if self.temporal is not None:
            self.temporal.change = "converge" if converging else change
            self.temporal.execute(encoder, buffers)
            self._mark(encoder, "temporal")
        self.tonemap.execute(encoder, buffers)
        self._mark(encoder, "tonemap")
        encoder.copy_buffer_to_buffer(buffers.get(self.tonemap.display), 0, self.readback, 0, self.display_bytes)
        if self.timer:
            self.timer.resolve(encoder, self.readback, self.display_bytes)
        ctx.device.queue.submit([encoder.finish()])
        raw = ctx.device.queue.read_buffer(self.readback)
        self.previous_frame = frame
        return RenderedFrame(frame, self.tonemap.image(raw[: self.display_bytes], self.width, self.height),
                             self.timer.stage_ms(raw[self.display_bytes:]) if self.timer else {})

    @property
    def spp_plane(self):
        return self.buffers.get(SPP)


def model_path(name: str, models_dir: str | Path | None = None) -> Path:
    """The ONNX file of network ``name`` (denoiser, error_predictor, confidence)."""
    folder = Path(models_dir) if models_dir else Path(str(resources.files("wgpu_rt.models")))
    return folder / MODEL_FILES[name]


def load_model(name: str, precision: str, models_dir=None, required: bool = True):
    path = model_path(name, models_dir)
    if not path.exists():
        if required:
            raise ModelError(f"{path}: no trained {name} model (train one into that folder)")
        return None
    from ..nn import WgslModel

    return WgslModel(path, precision)


def make_pipeline(scene, denoise: bool = True, adaptive: float | AdaptiveSettings | None = None,
                  temporal: bool | TemporalSettings = False, width: int = 256, height: int = 256,
                  max_depth: int = 8, seed: int = 0, operator: str = "aces", exposure: float = 0.0,
                  srgb: bool = True, output: str = "rgba8", precision: str = "fp32", models_dir=None, ctx=None,
                  denoiser=None, error_model=None, confidence_model=None) -> FramePipeline:
    """The FramePipeline ``render_frames`` runs (see there for the arguments), for callers that render
    frames one at a time: its setup (model loading, kernel compilation, first BVH build) is paid on the
    first ``render``, so timing the frames after it measures the steady state."""
    from ..accel.geometry import GeometryBuffers
    from ..gpu import get_context
    from ..trace.trace_pass import TracePass

    ctx = ctx or get_context()
    if isinstance(adaptive, (int, float)):
        adaptive = AdaptiveSettings(budget=float(adaptive))
    if temporal is True:
        temporal = TemporalSettings()
    temporal = temporal or None
    if denoise and denoiser is None:
        denoiser = load_model("denoiser", precision, models_dir)
    if adaptive is not None and adaptive.sampler == "heat" and error_model is None:
        error_model = load_model("error_predictor", precision, models_dir)
    if temporal is not None and confidence_model is None:
        confidence_model = load_model("confidence", precision, models_dir, required=False)
    traced: dict[bytes, TracePass] = {}   # the pass of the current geometry (object transforms)

    def trace_factory(frame: int, seed_frame: int):
        key = b"".join(m.transform_at(frame).tobytes() for m in scene.meshes)
        trace = traced.get(key)
        if trace is None:   # objects moved: new BVH, new uploads
            traced.clear()
            trace = traced[key] = TracePass(ctx, scene, GeometryBuffers.build(scene, frame), width, height,
                                            frame=frame, max_depth=max_depth, seed=seed + seed_frame)
        else:               # same geometry: only the camera and seed change
            trace.set_frame(scene, frame, seed + seed_frame)
        return trace

    return FramePipeline(ctx, width, height, trace_factory, denoiser=denoiser if denoise else None,
                         adaptive=adaptive, error_model=error_model, temporal=temporal,
                         confidence_model=confidence_model, operator=operator, exposure=exposure,
                         srgb=srgb, output=output)


def render_frames(scene, denoise: bool = True, adaptive: float | AdaptiveSettings | None = None,
                  temporal: bool | TemporalSettings = False, frames=None, **options) -> list[RenderedFrame]:
    """Render ``frames`` (default: every frame of the scene) to display images on the device.

    ``scene`` is a Scene, a built-in name or a scene-file path (``mesh`` for the built-in 'mesh').

    ``adaptive`` is a mean-spp budget for the Error-Predictor-guided sampler (or full AdaptiveSettings);
    ``temporal`` True uses the default TemporalSettings (with the Confidence Predictor when models/
    has one). ``options`` are ``make_pipeline``'s: width, height, max_depth, seed (frame f uses seed + f;
    the frames of a converging static view keep their first frame's), operator, exposure, srgb, output
    ("rgba8" or "f32"), precision ("fp32" or "fp16"), ctx, and the networks (denoiser, error_model,
    confidence_model) — those not given are loaded from ``models_dir`` (default: the packaged models/).
    """
    from ..scene import load_scene

    scene = load_scene(scene, mesh=options.pop("mesh", None))
    pipeline = make_pipeline(scene, denoise, adaptive, temporal, **options)
    frames = range(scene.frame_count) if frames is None else frames
    return [pipeline.render(scene, frame) for frame in frames]
