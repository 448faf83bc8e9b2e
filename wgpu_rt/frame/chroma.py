"""The denoised frame's colour balance held to what its own samples say.

The denoiser can shift hue over large areas: in a room lit mostly by light bounced off a green wall
(world-2147483667) it gives the walls and floor a greyer, redder cast than the samples' own mean has,
8 dB behind OIDN at 1 spp, and more samples do not cure it (the network's bias, not noise). The
samples' mean over a region is an unbiased estimate of the true mean there; the denoised frame's is
not. So over blocks of BLOCK×BLOCK pixels (Gaussian-weighted over neighbouring blocks, σ one block)
each colour channel's mean of the denoised frame F is moved towards the samples' mean N by a
James-Stein factor k = max(0, 1 − var / (N̄ − F̄)²), var being the estimated variance of N̄ (the
spread of N − F about its mean over each block, Σ(r − r̄)² / (n(n − 1)), weighed by the squared
Gaussian weights): a difference well beyond the noise is taken whole, one within it is left alone (so
fireflies, whose blocks have a large var, move nothing). Only the block's chromaticity — each channel's
share of the three channels' sum, ε added (SHARE_EPSILON times how much brighter than pack.STEPS_KEY the
frame is, frame/pack.py's ``steps_scale``: so the hold reads a frame alike at any scale of its light) — is
taken from the result, so brightness and its edges stay the denoiser's: F's pixels are scaled per channel
by share(target) / share(F̄), bilinear between block centres and clamped to [1/RATIO_LIMIT, RATIO_LIMIT].

BENCHMARKS.md §17: at 256² over 13 scenes +0.5 dB at 1, 4 and 16 spp (world-2147483667 +5 dB), FLIP
down on most. ``ChromaPass`` runs it on the device; ``match_sample_chroma`` is the numpy reference
(``denoise()``'s path).
"""

from __future__ import annotations

import numpy as np

from ..passes import RADIANCE, ComputePass
from .kernel import TILE, FrameKernel, ceil_div, gaussian_taps, nonnegative_finite, separable_blur
from .lowband import bilinear_up
from .pack import AS_TUNED, KEY_RATIO, block_sum, exposure_or_as_tuned, steps_scale
from .planes import DENOISED

BLOCK = 4                 # pixels per block side (wgsl/frame/block_grid.wgsl's BLOCK)
SIGMA_BLOCKS = 1.0        # the Gaussian's σ over the block grid, in blocks
RADIUS_BLOCKS = 3         # taps either side (3σ)
SHARE_EPSILON = 1e-4      # radiance added to each channel's mean before taking shares (near-black blocks stay),
                          # times the frame's pack.steps_scale
RATIO_LIMIT = 4.0         # a channel's scale factor stays in [1/4, 4]
STATISTICS_LIMIT = 1e18   # radiance clamped to this for the block statistics (so squares and sums stay finite)
F32_MAX = float(np.finfo(np.float32).max)


def chroma_ratios(denoised: np.ndarray, color: np.ndarray, exposure: float = AS_TUNED) -> np.ndarray:
    """(H, W, 3) denoised radiance F and samples' mean N → the (ceil(H/BLOCK), ceil(W/BLOCK), 3) per-block
    channel scale factors (the module docstring's rule; float64); ``exposure``: the frame's exposure scale
    (pack.frame_exposure), which scales ε (``steps_scale``)."""
    f = np.minimum(nonnegative_finite(denoised).astype(np.float64), STATISTICS_LIMIT)
    n = np.minimum(nonnegative_finite(color).astype(np.float64), STATISTICS_LIMIT)
    pixels = block_sum(np.ones(f.shape[:2]), BLOCK)[..., None]
    mean_f, mean_n = block_sum(f, BLOCK) / pixels, block_sum(n, BLOCK) / pixels
    # the residual's spread about its block mean (its mean is the bias sought, not noise), as the
    # variance of the block's mean: Σ(r − r̄)² / (n (n − 1))
    residual = n - f - np.repeat(np.repeat(mean_n - mean_f, BLOCK, 0), BLOCK, 1)[:f.shape[0], :f.shape[1]]
    spread = block_sum(residual * residual, BLOCK) / (pixels * np.maximum(pixels - 1, 1))
    taps = gaussian_taps(SIGMA_BLOCKS, RADIUS_BLOCKS)
    low_f, low_n = separable_blur(mean_f, taps), separable_blur(mean_n, taps)
    variance = separable_blur(spread, taps * taps)
    difference2 = (low_n - low_f) ** 2
    k = np.where(variance < difference2, 1.0 - variance / np.where(difference2 > 0, difference2, 1.0), 0.0)
    epsilon = SHARE_EPSILON * steps_scale(exposure)
    target = np.maximum(low_f + k * (low_n - low_f), 0.0) + epsilon
    low_f = low_f + epsilon
    ratio = (target / target.sum(-1, keepdims=True)) / (low_f / low_f.sum(-1, keepdims=True))
    return np.clip(ratio, 1.0 / RATIO_LIMIT, RATIO_LIMIT)


def match_sample_chroma(denoised: np.ndarray, color: np.ndarray, exposure: float = AS_TUNED) -> np.ndarray:
    """(H, W, 3) denoised radiance, its samples' (H, W, 3) mean (and the frame's exposure scale,
    ``chroma_ratios``) → the denoised radiance with each block's chromaticity moved to what the samples
    support (float32, finite, ≥ 0)."""
    height, width = np.shape(denoised)[:2]
    ratio = bilinear_up(chroma_ratios(denoised, color, exposure), BLOCK, (height, width))
    return np.minimum(nonnegative_finite(denoised) * ratio, F32_MAX).astype(np.float32)


class ChromaPass(ComputePass):
    """``match_sample_chroma`` on the device: DENOISED rewritten in place against RADIANCE (three
    dispatches: block statistics, per-block ratios over the Gaussian's window, per-pixel scaling);
    ``exposure``: a WhiteBalancePass's result, whose fourth value is the frame's exposure scale (None:
    pack.AS_TUNED, ε as it is)."""

    inputs = (RADIANCE, DENOISED)
    outputs = (DENOISED,)

    def __init__(self, ctx, width: int, height: int, exposure=None):
        self.exposure = exposure_or_as_tuned(ctx, exposure)
        self.blocks = (ceil_div(width, BLOCK), ceil_div(height, BLOCK))
        count = self.blocks[0] * self.blocks[1]
        self.statistics = ctx.storage(4 * 9 * count, label="chroma block statistics")
        self.ratios = ctx.storage(4 * 3 * count, label="chroma ratios")
        # offsets 0 … RADIUS_BLOCKS (the kernel's TAP_k)
        taps = gaussian_taps(SIGMA_BLOCKS, RADIUS_BLOCKS)[RADIUS_BLOCKS:]
        constants = {"SHARE_EPSILON": SHARE_EPSILON, "KEY_RATIO": KEY_RATIO, "RATIO_LIMIT": RATIO_LIMIT,
                     "STATISTICS_LIMIT": STATISTICS_LIMIT,
                     **{f"TAP_{k}": float(tap) for k, tap in enumerate(taps)}}
        names = ("color", "denoised", "statistics", "ratios", "exposure")
        self.kernels = [FrameKernel(ctx, "frame/chroma.wgsl", entry, uses, width, height, constants)
                        for entry, uses in (("chroma_statistics", names[:3]), ("chroma_ratios", names[2:]),
                                            ("chroma_apply", ("denoised", "ratios")))]

    def execute(self, encoder, buffers) -> None:
        bound = {"color": buffers.get(RADIANCE), "denoised": buffers.get(DENOISED),
                 "statistics": self.statistics, "ratios": self.ratios, "exposure": self.exposure}
        block_groups = (ceil_div(self.blocks[0], TILE), ceil_div(self.blocks[1], TILE))
        statistics, ratios, apply = self.kernels
        statistics.dispatch(encoder, bound, groups=block_groups)
        ratios.dispatch(encoder, bound, groups=block_groups)
        apply.dispatch(encoder, bound)
