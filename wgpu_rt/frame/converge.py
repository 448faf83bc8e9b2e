"""Converge: a frame of n samples per pixel shown as its denoised frame blended with the raw mean, per
pixel, by how much each can be trusted there (wgsl/frame/converge.wgsl has the rule). The mean's
error is estimated from a copy of the running mean taken after its first h samples (HALF_RADIANCE and
HALF_SPP, which the frame pipeline copies: after the first half of a frame's samples, or under a
static camera whenever the samples since the last copy reach those before it); the denoiser's error is
what the difference between the two frames holds beyond that, both averaged over the pixels of a
(2·RADIUS + 1)² window that took samples after the copy, each pixel's squared differences weighed by
how much they show on screen (display_slope2) and each neighbour by how alike its denoised value looks
to the centre's (CONVERGE_TAU). Used for a frame of several spp and by
temporal mode's static camera."""

from __future__ import annotations

import numpy as np

from ..metrics import DISPLAY_GAMMA, to_display
from ..passes import RADIANCE, SPP, ComputePass, PlaneSpec
from .adaptive import HALF_RADIANCE
from .kernel import FrameKernel, ceil_div, nonnegative_finite
from .planes import DENOISED

CONVERGED = PlaneSpec("converged", 3)
HALF_SPP = PlaneSpec("half_spp", 1, "u32")   # the samples HALF_RADIANCE holds
# The window's radius and the cap's scale: first fitted with benchmarks/bench_converge.py (BENCHMARKS.md §8, §11:
# 64², 7×7 window, scale 1024), then refitted at 256² (§43: the 24 held-out worlds and four built-ins, 16 and 64
# spp, Mitsuba's 4096-spp gold): a 15×15 window averages the mean's split and the difference over enough
# pixels that a split which happens to agree no longer reads as a converged mean (…650 at 16 spp lost 2.4 dB
# to the 7×7 window), and with that steadier estimate the cap can let the mean in sooner (scale 384: at most
# 16/(16 + 384) of a 4-spp frame, 0.4 of a 16-spp one, 0.91 of a 64-spp one).
CONVERGE_RADIUS = 7      # a const in the kernel (its workgroup tile is sized by it); parity tests hold them equal
CONVERGE_CAP_SCALE = 384.0
CONVERGE_TILE = (8, 4)   # the kernel's workgroup: with its RADIUS-wide halo it fits 16 KiB of workgroup memory
# A neighbour counts in the window by how alike its denoised value looks on screen: weight
# exp(−Δ² / 2τ²) of the difference Δ of display values (BENCHMARKS.md §11: one bright pixel whose
# halves disagree, a caustic, no longer makes its whole window keep the denoised frame).
CONVERGE_TAU = 0.05
# Squared differences are weighed by the squared slope of the display transform the quality metrics
# use (wgpu_rt.metrics: x / (1 + x), gamma 2.2) at the denoised value, floored here so that a black
# pixel's slope stays finite (BENCHMARKS.md §11: without it, a dark pixel beside brighter noisy ones
# kept a denoised value whose tiny linear error is large on screen).
SLOPE_GAMMA = DISPLAY_GAMMA
SLOPE_FLOOR = 1e-4
F32_MAX = float(np.finfo(np.float32).max)


def half_count(n: int) -> int:
    """The samples after which a frame of ``n`` spp copies its running mean: n // 2."""
    return n // 2


def window_sums(image: np.ndarray, radius: int, valid: np.ndarray, key: np.ndarray,
                tau: float) -> tuple[np.ndarray, np.ndarray]:
    """(H, W, C) sums of ``image`` over the ``valid`` (H, W, 1) pixels of each pixel's (2·radius + 1)²
    window, cut at the image's edges, each neighbour weighed by exp(−(key_j − key_i)² / 2τ²), how alike
    its (H, W, C) ``key`` is to the centre's (float64); and (H, W, C) the sums of those weights."""
    height, width = image.shape[:2]
    pad = ((radius, radius), (radius, radius), (0, 0))
    padded = np.pad(np.where(valid, np.asarray(image, np.float64), 0.0), pad)
    inside = np.pad(np.broadcast_to(valid, key.shape).astype(np.float64), pad)
    keys = np.pad(np.asarray(key, np.float64), pad)
    sums, weights = np.zeros(key.shape), np.zeros(key.shape)
    for dy in range(2 * radius + 1):
        for dx in range(2 * radius + 1):
            alike = keys[dy:dy + height, dx:dx + width] - key
            weight = inside[dy:dy + height, dx:dx + width] * np.exp(-alike * alike / (2.0 * tau * tau))
            sums += weight * padded[dy:dy + height, dx:dx + width]
            weights += weight
    return sums, weights


def display_slope2(value: np.ndarray) -> np.ndarray:
    """Squared derivative of (x / (1 + x))^(1/2.2) at max(value, SLOPE_FLOOR): how much a small linear
    error at that value weighs on screen."""
    x = np.maximum(value, SLOPE_FLOOR)
    return ((x / (1.0 + x)) ** (1.0 / SLOPE_GAMMA - 1.0) / (SLOPE_GAMMA * (1.0 + x) ** 2)) ** 2


def converge(denoised, samples_mean, spp, half_mean, half_spp, radius: int = CONVERGE_RADIUS,
             cap_scale: float = CONVERGE_CAP_SCALE, on_screen: bool = True,
             tau: float = CONVERGE_TAU) -> np.ndarray:
    """Numpy reference of the converge pass: (H, W, 3) denoised frame and mean of ``spp`` (H, W) samples,
    and the mean of their first ``half_spp`` (H, W) → (H, W, 3) blend, finite and ≥ 0. ``on_screen=False``
    sums the squared differences unweighed; with ``tau=inf`` and ``radius=2`` that is the rule before
    BENCHMARKS.md §11 (for comparison)."""
    denoised = nonnegative_finite(denoised).astype(np.float64)
    mean = nonnegative_finite(samples_mean).astype(np.float64)
    half = nonnegative_finite(half_mean).astype(np.float64)
    spp, first = np.asarray(spp, np.int64)[..., None], np.asarray(half_spp, np.int64)[..., None]
    estimated = spp > first
    slope2 = display_slope2(denoised) if on_screen else np.ones_like(denoised)
    key = to_display(denoised)
    with np.errstate(over="ignore", invalid="ignore"):
        # the kernel squares in f32 before weighing: a square over F32_MAX is inf there
        split2, difference2 = (np.where(x * x > F32_MAX, np.inf, x * x) for x in (mean - half, denoised - mean))
        each = slope2 * (split2 * first / np.maximum(spp - first, 1))
        differences = slope2 * difference2
        variance_sums, window = window_sums(each, radius, estimated, key, tau)
        difference_sums, _ = window_sums(differences, radius, estimated, key, tau)
        window = np.maximum(window, 1.0)
        sigma2 = variance_sums / window
        error2 = np.maximum(difference_sums / window - sigma2, 0.0)
        samples = np.maximum(spp, 1).astype(np.float64)
        cap = samples ** 2 / (samples ** 2 + cap_scale)
        total = error2 + sigma2
        weight = np.where(total > 0, np.minimum(error2 / np.where(total > 0, total, 1.0), cap), cap)
        # where the kernel's f32 sums overflow (inf − inf: NaN here), it keeps the denoised value
        overflow = (variance_sums > F32_MAX) | (difference_sums > F32_MAX) | (total > F32_MAX)
        weight = np.where(overflow | ~estimated, 0.0, weight)
    return (denoised + weight * (mean - denoised)).astype(np.float32)


def copy_half(encoder, buffers) -> None:
    """Record the copy of the running mean and its counts (HALF_RADIANCE, HALF_SPP) that the blend
    measures the mean's error by."""
    for source, copy in ((RADIANCE, HALF_RADIANCE), (SPP, HALF_SPP)):
        encoder.copy_buffer_to_buffer(buffers.get(source), 0, buffers.get(copy), 0,
                                      source.nbytes(buffers.width, buffers.height))


class ConvergePass(ComputePass):
    """``source`` (a denoised frame), the tracer's radiance and spp planes and their copies after the first
    part of the samples (HALF_RADIANCE, HALF_SPP) → converged (3 planes)."""

    outputs = (CONVERGED,)

    def __init__(self, ctx, width: int, height: int, source: PlaneSpec = DENOISED):
        self.source = source
        self.inputs = (source, RADIANCE, SPP, HALF_RADIANCE, HALF_SPP)
        self.kernel = FrameKernel(ctx, "frame/converge.wgsl", "main",
                                  ("denoised", "samples_mean", "spp", "half_mean", "half_spp", "converged"),
                                  width, height, {"CAP_SCALE": CONVERGE_CAP_SCALE, "TAU": CONVERGE_TAU,
                                   "SLOPE_GAMMA": SLOPE_GAMMA, "SLOPE_FLOOR": SLOPE_FLOOR})
        self.groups = (ceil_div(width, CONVERGE_TILE[0]), ceil_div(height, CONVERGE_TILE[1]))   # 8×4 tiles

    def execute(self, encoder, buffers) -> None:
        self.kernel.dispatch(encoder, {"denoised": buffers.get(self.source), "samples_mean": buffers.get(RADIANCE),
                                       "spp": buffers.get(SPP), "half_mean": buffers.get(HALF_RADIANCE),
                                       "half_spp": buffers.get(HALF_SPP), "converged": buffers.get(CONVERGED)},
                             self.groups)
