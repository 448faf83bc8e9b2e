"""Edge-aware smoothing of what the denoiser leaves: an à-trous filter guided by the G-buffers.

The network leaves residue a few pixels wide (blotches between 1 and 8 pixels: on the worlds furthest
behind OIDN at 256², 2–4× OIDN's error in that band, BENCHMARKS.md §17), while the G-buffers say which
neighbours show the same surface. So the denoised frame F is smoothed by the edge-avoiding à-trous
wavelet filter of Dammertz et al. (HPG 2010, as SVGF uses it): STEPS passes of a 5×5 B3-spline kernel
whose taps lie STEP pixels apart (1, 2, 4: a 25-pixel reach for 75 taps), each tap weighed by how alike
the two pixels are in albedo, normal, relative depth and display luminance of the current pass's input
(x/(1+x))^(1/2.2) of the channel mean, the metric's own display, read at the frame's exposure brought to
pack.STEPS_KEY: the irradiance's key, frame/pack.py's ``frame_exposure``), so edges in any of them stop it
and a frame is filtered alike at any scale of its light (at the frame's own scale a bright frame saturated
the display and was smoothed across its edges: `cornell` at 2^8 of its light lost 11 dB, BENCHMARKS.md §40).
The luminance tolerance narrows as the centre pixel's samples grow past FADE_SPP, by sqrt(FADE_SPP / spp):
what the denoiser leaves shrinks with the noise it was given. Indices are clamped at the frame's edges.
Radiance and depth are clamped to FILTER_LIMIT first, so the weighted sums stay finite and the reciprocal
of a depth stays a normal float (NVIDIA flushes subnormal ones to 0).

BENCHMARKS.md §17: +0.50 dB over 13 scenes at 256² and 1 spp, +0.74 over 6 at 512², every scene up.
``AtrousPass`` runs it on the device; ``atrous_filter`` is the numpy reference (``denoise()``'s path).
"""

from __future__ import annotations

import numpy as np

from ..passes import ALBEDO, DEPTH, NORMAL, SPP, ComputePass
from .kernel import FrameKernel, finite, nonnegative_finite
from .pack import AS_TUNED, KEY_RATIO, exposure_or_as_tuned, steps_scale
from .planes import DENOISED

STEPS = (1, 2, 4)            # tap spacing of each pass, in pixels
B3_SPLINE = (1 / 16, 1 / 4, 3 / 8, 1 / 4, 1 / 16)
SIGMA_LUMINANCE = 0.02       # display luminance (x/(1+x))^(1/2.2), up to FADE_SPP samples a pixel
FADE_SPP = 16                # beyond it, SIGMA_LUMINANCE · sqrt(FADE_SPP / spp)
SIGMA_ALBEDO = 0.05          # Euclidean distance of albedo RGB
SIGMA_NORMAL = 0.1           # Euclidean distance of the normal planes
SIGMA_DEPTH = 0.02           # depth difference relative to the centre's depth (floored at DEPTH_FLOOR)
DEPTH_FLOOR = 1e-3
GUIDE_BYTES = 32             # a pixel's guides in the pass's buffer: 8 floats, the widest plane it holds
DISPLAY_GAMMA = 2.2
FILTER_LIMIT = 1e30          # radiance and depth clamped to this before filtering
LUMINANCE_FACTOR_LIMIT = 1e8   # at most this factor on radiance ≤ FILTER_LIMIT, so its product stays finite


def luminance_factor(exposure: float) -> float:
    """The factor on radiance that brings a frame of exposure scale ``exposure`` (pack.frame_exposure) to
    pack.STEPS_KEY, at most LUMINANCE_FACTOR_LIMIT."""
    return float(min(np.float32(1.0) / np.float32(steps_scale(exposure)), LUMINANCE_FACTOR_LIMIT))


def display_luminance(radiance: np.ndarray, factor: float = 1.0) -> np.ndarray:
    """(H, W, 3) radiance → (H, W): the channel mean m times ``factor``, as (m / (1 + m))^(1/2.2)
    (float64)."""
    mean = (radiance / 3.0).sum(-1) * factor
    return (mean / (1.0 + mean)) ** (1.0 / DISPLAY_GAMMA)


def luminance_sigma(spp, shape: tuple[int, int]) -> np.ndarray:
    """(H, W) tolerance in display luminance for pixels of ``spp`` samples (one count or an (H, W[, 1])
    map; non-finite counts as 0): SIGMA_LUMINANCE up to FADE_SPP, then · sqrt(FADE_SPP / spp)."""
    counts = np.nan_to_num(np.broadcast_to(np.asarray(spp, np.float64).reshape(np.shape(spp)[:2]), shape),
                           nan=0.0, posinf=0.0, neginf=0.0)
    return SIGMA_LUMINANCE * np.sqrt(FADE_SPP / np.maximum(counts, FADE_SPP))


def atrous_filter(denoised: np.ndarray, albedo: np.ndarray, normal: np.ndarray, depth: np.ndarray,
                  spp=1, exposure: float = AS_TUNED) -> np.ndarray:
    """(H, W, 3) denoised radiance and its (H, W, 3) albedo, (H, W, 3) normal and (H, W[, 1]) depth planes
    and sample counts (one count or an (H, W[, 1]) map), and the frame's exposure scale
    (pack.frame_exposure) → the radiance after the STEPS passes of the module docstring (float32, finite,
    ≥ 0)."""
    factor = luminance_factor(exposure)
    height, width = np.shape(denoised)[:2]
    sigma = luminance_sigma(spp, (height, width))
    out = np.minimum(nonnegative_finite(denoised).astype(np.float64), FILTER_LIMIT)
    albedo = nonnegative_finite(albedo).astype(np.float64)
    normal = finite(normal).astype(np.float64)
    depth = np.minimum(nonnegative_finite(np.reshape(depth, (height, width))).astype(np.float64), FILTER_LIMIT)
    depth_scale = np.maximum(depth, DEPTH_FLOOR)
    rows, cols = np.arange(height), np.arange(width)
    for step in STEPS:
        luminance = display_luminance(out, factor)
        total, weights = np.zeros_like(out), np.zeros((height, width, 1))
        for i, dy in enumerate(range(-2, 3)):
            r = np.clip(rows + dy * step, 0, height - 1)[:, None]
            for j, dx in enumerate(range(-2, 3)):
                c = np.clip(cols + dx * step, 0, width - 1)[None, :]
                exponent = ((luminance[r, c] - luminance) ** 2 / (2 * sigma * sigma)
                            + ((albedo[r, c] - albedo) ** 2).sum(-1) / (2 * SIGMA_ALBEDO ** 2)
                            + ((normal[r, c] - normal) ** 2).sum(-1) / (2 * SIGMA_NORMAL ** 2)
                            + ((depth[r, c] - depth) / depth_scale) ** 2 / (2 * SIGMA_DEPTH ** 2))
                weight = (B3_SPLINE[i] * B3_SPLINE[j] * np.exp(-exponent))[..., None]
                total += weight * out[r, c]
                weights += weight
        out = total / weights
    return out.astype(np.float32)


class AtrousPass(ComputePass):
    """``atrous_filter`` on the device: DENOISED smoothed in place. A first dispatch lays out what every
    tap reads per pixel, side by side (the radiance with its display luminance; the guides with the
    pixel's luminance tolerance), then one dispatch per step ping-pongs between two work buffers, the
    last writing DENOISED. ``exposure``: a WhiteBalancePass's result, whose fourth value is the frame's
    exposure scale (None: pack.AS_TUNED, the radiance's display luminance as it is)."""

    inputs = (DENOISED, ALBEDO, NORMAL, DEPTH, SPP)
    outputs = (DENOISED,)

    def __init__(self, ctx, width: int, height: int, exposure=None):
        self.exposure = exposure_or_as_tuned(ctx, exposure)
        pixels = width * height
        self.work = [ctx.storage(16 * pixels, label=f"a-trous work {k}") for k in range(2)]
        self.guides = ctx.storage(GUIDE_BYTES * pixels, label="a-trous guides")
        constants = {"SIGMA_LUMINANCE": SIGMA_LUMINANCE, "FADE_SPP": FADE_SPP, "SIGMA_ALBEDO": SIGMA_ALBEDO,
                     "SIGMA_NORMAL": SIGMA_NORMAL, "SIGMA_DEPTH": SIGMA_DEPTH, "DEPTH_FLOOR": DEPTH_FLOOR,
                     "FILTER_LIMIT": FILTER_LIMIT, "KEY_RATIO": KEY_RATIO,
                     "LUMINANCE_FACTOR_LIMIT": LUMINANCE_FACTOR_LIMIT}
        self.prepare = FrameKernel(ctx, "frame/atrous.wgsl", "atrous_prepare",
                                   ("denoised", "work_out", "albedo", "normal", "depth", "spp", "guides",
                                    "exposure"),
                                   width, height, constants)
        # a step recomputes its output's luminance (reading the exposure); the last writes radiance only
        self.steps = [FrameKernel(ctx, "frame/atrous.wgsl", entry, uses, width, height, {**constants, "STEP": step})
                      for step, (entry, uses) in zip(STEPS, [("atrous_step", ("work_in", "work_out", "guides",
                                                                              "exposure"))] * (len(STEPS) - 1)
                                                     + [("atrous_last", ("work_in", "denoised", "guides"))])]

    def execute(self, encoder, buffers) -> None:
        bound = {"denoised": buffers.get(DENOISED), "albedo": buffers.get(ALBEDO), "normal": buffers.get(NORMAL),
                 "depth": buffers.get(DEPTH), "spp": buffers.get(SPP), "guides": self.guides,
                 "exposure": self.exposure}
        self.prepare.dispatch(encoder, {**bound, "work_out": self.work[0]})
        for k, kernel in enumerate(self.steps):
            kernel.dispatch(encoder, {**bound, "work_in": self.work[k % 2], "work_out": self.work[(k + 1) % 2]})
