"""Temporal stability: reprojected, disocclusion-tested, clamped history blended with the denoised frame.

See ``wgsl/frame/temporal.wgsl`` for the algorithm. Which path a frame takes depends on how it relates
to the previous one (``frame_change``): a cut (first frame, skipped frames, a camera jump) clears the
history; a static camera over a static scene accumulates plainly (no reprojection or clamping, so noise
averages out over up to ``max_frames`` frames); anything else reprojects and blends. ``converge`` (set
by the frame pipeline, which keeps accumulating the tracer's samples under a static camera, so the
source is the denoised mean of all of them) runs the converge pass (``frame/converge.py``: per pixel, the
raw mean where it has converged, the denoised frame where not) and takes the result whole as the new
history.

Confidence (the optional Confidence Predictor's output c) is read as trust in the history: α =
mix(1, 0.01, t) with t = max(c − floor, 0) / (1 − floor), so 1 keeps 99 % history and anything at or
below ``confidence_floor`` takes the current frame (floor 0 is the plain mix(1, 0.01, c)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import WgpuRtError
from ..passes import DEPTH, MOTION, NORMAL, RADIANCE, ComputePass, PlaneSpec, prepare_network
from .converge import CONVERGED, ConvergePass
from .kernel import FrameKernel, finite, nonnegative_finite
from .denoise_chain import reads_at_one_key
from .pack import CONFIDENCE_KEY, PackConfidencePass, RadianceExposurePass
from .planes import CONFIDENCE_INPUT

CLAMP_MODES = ("none", "box", "variance")
HISTORY = PlaneSpec("history", 8)           # RGB, depth, normal xyz, history length
REPROJECTED = PlaneSpec("reprojected", 5)   # RGB, previous depth, history length (0 = disoccluded)
CONFIDENCE = PlaneSpec("confidence", 1)
TEMPORAL = PlaneSpec("temporal", 3)
# The bindings each entry point of frame/temporal.wgsl uses (their indices are read from the WGSL).
ENTRY_BINDINGS = {
    "reproject": ("depth", "normal", "motion", "history", "reprojected"),
    "blend": ("color", "depth", "normal", "history", "reprojected", "confidence", "output"),
    "accumulate": ("color", "depth", "normal", "history", "output"),
    "converge": ("color", "depth", "normal", "history", "output"),
}
CUT_ANGLE_DEGREES = 30.0
CUT_DISTANCE_FRACTION = 0.25


@dataclass(frozen=True)
class TemporalSettings:
    clamp: str = "variance"        # history clamp: none, box (3×3 min/max) or variance (mean ± γσ)
    # Width of the variance box in standard deviations. 2, not the 1 usual for raw TAA input: the
    # neighbourhood of a denoised frame is smooth, so a 1σ box pulls history toward the current
    # frame and lets its frame-to-frame wobble through (bench_temporal.py on `moving`: flicker
    # 0.0047 → 0.0035 at 64², disocclusion error unchanged).
    gamma: float = 2.0
    max_frames: int = 32           # α never drops below 1/max_frames
    depth_tolerance: float = 0.05  # relative depth difference that still counts as the same surface
    normal_threshold: float = 0.9  # smallest normal dot product that counts as the same surface
    # Confidence at or below this keeps no history; above it, trust rises linearly to 1. The network
    # learns with class-balanced weights, so its low outputs are not probabilities. bench_temporal.py
    # --confidence-floor F on `moving` (96², 16 frames, session 3's denoiser and confidence model),
    # disocclusion relMSE minus per-frame denoising's
    # (mean ± s.e. over frames) / flicker: F 0 +0.0097 ± 0.0086 / 0.00234; 0.3 +0.0002 ± 0.0008 /
    # 0.00245; 0.4 +0.0006 ± 0.0004 / 0.00249; 0.5 +0.0004 ± 0.0003 / 0.00255.
    confidence_floor: float = 0.3

    def __post_init__(self):
        if self.clamp not in CLAMP_MODES:
            raise WgpuRtError(f"temporal clamp {self.clamp!r} is not one of {', '.join(CLAMP_MODES)}")
        if not (self.max_frames >= 1 and self.gamma > 0 and 0 <= self.confidence_floor < 1):
            raise WgpuRtError(f"temporal max_frames must be ≥ 1, gamma > 0, confidence_floor in [0, 1), got "
                              f"{self.max_frames}, {self.gamma}, {self.confidence_floor}")

    def constants(self) -> dict:
        return {"CLAMP_MODE": CLAMP_MODES.index(self.clamp), "GAMMA": self.gamma,
                "MAX_FRAMES": self.max_frames, "DEPTH_TOLERANCE": self.depth_tolerance,
                "NORMAL_THRESHOLD": self.normal_threshold, "CONFIDENCE_FLOOR": self.confidence_floor}


def frame_change(scene, previous_frame: int | None, frame: int) -> str:
    """How ``frame`` relates to ``previous_frame``: ``cut`` (no usable history: first frame, a jump in
    time, or a camera move beyond CUT_ANGLE_DEGREES / CUT_DISTANCE_FRACTION of the view distance),
    ``static`` (same camera, object transforms and lights) or ``moving``."""
    if previous_frame is None or frame - previous_frame != 1:
        return "cut"
    before, now = scene.camera_at(previous_frame), scene.camera_at(frame)
    forward_before = before.basis()[2]
    forward_now = now.basis()[2]
    angle = np.degrees(np.arccos(np.clip(np.dot(forward_before, forward_now), -1.0, 1.0)))
    view_distance = float(np.linalg.norm(before.target - before.origin))
    if angle > CUT_ANGLE_DEGREES or np.linalg.norm(now.origin - before.origin) > CUT_DISTANCE_FRACTION * view_distance:
        return "cut"
    same_camera = (np.array_equal(before.origin, now.origin) and np.array_equal(before.target, now.target)
                   and np.array_equal(before.up, now.up) and before.fov == now.fov)
    same_objects = all(m.pose_key(previous_frame) == m.pose_key(frame) for m in scene.meshes)
    same_lights = not scene.has_moving_lights or scene.lights_key(previous_frame) == scene.lights_key(frame)
    return "static" if same_camera and same_objects and same_lights else "moving"


# -- numpy references (images (H, W, C); history (H, W, 8), reprojected (H, W, 5)) ---------------------
def _surfaces_match(history_texel, current_depth, current_normal, settings):
    previous_depth = history_texel[3]
    if current_depth <= 0 or previous_depth <= 0:
        return current_depth <= 0 and previous_depth <= 0
    if abs(previous_depth - current_depth) > settings.depth_tolerance * current_depth:
        return False
    return float(np.dot(history_texel[4:7], current_normal)) >= settings.normal_threshold


def reproject_history(history, depth, normal, motion, settings=TemporalSettings()) -> np.ndarray:
    """Bilinear, disocclusion-tested lookup of ``history`` at each pixel's previous position."""
    height, width = depth.shape[:2]
    depth = nonnegative_finite(depth).reshape(height, width)
    normal = finite(normal)
    out = np.zeros((height, width, 5), np.float64)
    for y in range(height):
        for x in range(width):
            mx, my = motion[y, x]
            if not (np.isfinite(mx) and np.isfinite(my)):
                continue
            px, py = np.float32(x + mx), np.float32(y + my)
            bx, by = np.floor(px), np.floor(py)
            fx, fy = px - bx, py - by
            total, weight = np.zeros(5), 0.0
            for ox, oy in ((0, 0), (1, 0), (0, 1), (1, 1)):
                w = (fx if ox else 1 - fx) * (fy if oy else 1 - fy)
                tx, ty = int(bx) + ox, int(by) + oy
                if w <= 0 or not (0 <= tx < width and 0 <= ty < height):
                    continue
                texel = history[ty, tx]
                if texel[7] <= 0 or not _surfaces_match(texel, depth[y, x], normal[y, x], settings):
                    continue
                total += w * texel[[0, 1, 2, 3, 7]]
                weight += w
            if weight > 1e-3:
                out[y, x] = total / weight
    return out.astype(np.float32)


def _neighbourhood_clamp(color, value, y, x, settings):
    height, width = color.shape[:2]
    ys = np.clip(np.arange(y - 1, y + 2), 0, height - 1)
    xs = np.clip(np.arange(x - 1, x + 2), 0, width - 1)
    window = color[np.ix_(ys, xs)].reshape(9, 3).astype(np.float64)
    low, high = window.min(0), window.max(0)
    if settings.clamp == "variance":
        mean = window.mean(0)
        sigma = np.sqrt(np.maximum((window ** 2).mean(0) - mean ** 2, 0))
        low, high = np.maximum(mean - settings.gamma * sigma, 0), mean + settings.gamma * sigma
    return np.clip(value, low, high)


def _new_history(output, depth, normal, length):
    return np.concatenate([output, nonnegative_finite(depth).reshape(output.shape[:2] + (1,)),
                           finite(normal), length[..., None]], axis=-1).astype(np.float32)


def blend_history(color, depth, normal, reprojected, confidence=None, settings=TemporalSettings()):
    """(output (H, W, 3), new history (H, W, 8)) of the blend step."""
    color = nonnegative_finite(color)
    output = color.astype(np.float64).copy()
    length = np.ones(color.shape[:2])
    for y, x in zip(*np.nonzero(reprojected[..., 4] > 0)):
        previous = reprojected[y, x, :3].astype(np.float64)
        if settings.clamp != "none":
            previous = _neighbourhood_clamp(color, previous, y, x, settings)
        count = reprojected[y, x, 4]
        alpha = 1.0 / (count + 1.0)
        if confidence is not None:
            trust = (max(np.clip(finite(confidence[y, x]), 0, 1) - settings.confidence_floor, 0.0)
                     / (1.0 - settings.confidence_floor))
            alpha = 1.0 + (0.01 - 1.0) * trust
        alpha = max(alpha, 1.0 / settings.max_frames)
        output[y, x] = previous + alpha * (color[y, x] - previous)
        length[y, x] = min(count + 1.0, settings.max_frames)
    return output.astype(np.float32), _new_history(output, depth, normal, length)


def accumulate_history(color, depth, normal, history, settings=TemporalSettings()):
    """(output, new history) of plain per-pixel accumulation (static camera and scene)."""
    count = history[..., 7].astype(np.float64)
    alpha = np.maximum(1.0 / (count + 1.0), 1.0 / settings.max_frames)[..., None]
    previous = history[..., :3].astype(np.float64)
    output = previous + alpha * (nonnegative_finite(color) - previous)
    return output.astype(np.float32), _new_history(output, depth, normal, np.minimum(count + 1, settings.max_frames))


# -- the pass -----------------------------------------------------------------------------------------
class TemporalPass(ComputePass):
    """``source`` (the denoised frame), depth, normal, motion, history → temporal (3 planes), history.

    Each execute is told the frame's ``change`` (``frame_change``'s answer, or ``converge``: the source is
    the denoised mean of every sample of a static view, in the radiance and spp planes, and the pipeline
    keeps the converge pass's copy of them, ``converge.copy_half``). With a
    ``confidence`` network (an object with ``record(encoder, input_buffer, height, width) ->
    output_buffer``, such as ``wgpu_rt.nn.WgslModel``) and the frame's ``depth_max`` buffer, moving frames run the Confidence
    Predictor on the packed (current, reprojected) pair and blend by its output; ``auto_exposure`` as
    ``reads_at_one_key`` takes it (None: as the model was trained).
    """

    outputs = (TEMPORAL, HISTORY)

    def __init__(self, ctx, width: int, height: int, source: PlaneSpec,
                 settings: TemporalSettings = TemporalSettings(), confidence=None, depth_max=None,
                 auto_exposure: bool | None = None):
        if confidence is not None and depth_max is None:
            raise ValueError("a confidence model needs the frame's depth_max buffer")
        self.ctx, self.width, self.height = ctx, width, height
        self.source, self.settings, self.confidence = source, settings, confidence
        # Without a denoiser the source is the sample mean itself: nothing to hand over, it is taken whole.
        self.converge = ConvergePass(ctx, width, height, source) if source != RADIANCE else None
        self.inputs = (source, DEPTH, NORMAL, MOTION, *(self.converge.inputs[1:] if self.converge else ()))
        constants = {**settings.constants(), "USE_CONFIDENCE": confidence is not None}
        self.kernels = {entry: FrameKernel(ctx, "frame/temporal.wgsl", entry, bindings, width, height,
                                           constants)
                        for entry, bindings in ENTRY_BINDINGS.items()}
        # A confidence model trained with the exposure step reads the frame and its history at one key.
        self.confidence_exposure = (RadianceExposurePass(ctx, width, height, CONFIDENCE_KEY, source)
                                    if confidence is not None and reads_at_one_key(confidence, auto_exposure) else None)
        self.pack_confidence = (PackConfidencePass(ctx, width, height, source, REPROJECTED, depth_max,
                                                   getattr(self.confidence_exposure, "result", None))
                                if confidence is not None else None)

    def prepare(self, buffers) -> None:
        """Build ahead the confidence network's plan (frame.pipeline's ``prepare``)."""
        if self.confidence is not None:
            prepare_network(self.confidence, buffers.get(CONFIDENCE_INPUT), self.height, self.width)

    def execute(self, encoder, buffers, change: str) -> None:
        planes = {"color": buffers.get(self.source), "depth": buffers.get(DEPTH),
                  "normal": buffers.get(NORMAL), "history": buffers.get(HISTORY),
                  "output": buffers.get(TEMPORAL)}
        if change == "converge":
            if self.converge is not None:
                self.converge.execute(encoder, buffers)
                planes["color"] = buffers.get(CONVERGED)
            self.kernels["converge"].dispatch(encoder, planes)
            return
        if change in ("cut", "static"):
            if change == "cut":
                encoder.clear_buffer(planes["history"])
            self.kernels["accumulate"].dispatch(encoder, planes)
            return
        if change != "moving":
            raise ValueError(f"unknown frame change {change!r}")
        planes |= {"motion": buffers.get(MOTION), "reprojected": buffers.get(REPROJECTED)}
        self.kernels["reproject"].dispatch(encoder, planes)
        if self.confidence is not None:
            if self.confidence_exposure is not None:
                self.confidence_exposure.execute(encoder, buffers)
            self.pack_confidence.execute(encoder, buffers)
            confidence = self.confidence.record(encoder, buffers.get(CONFIDENCE_INPUT), self.height, self.width)
        else:
            confidence = buffers.get(CONFIDENCE)   # bound but never read
        self.kernels["blend"].dispatch(encoder, planes | {"confidence": confidence})
