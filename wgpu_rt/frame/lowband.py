"""The denoised frame's low band from a second denoiser pass at half resolution.

The denoiser was trained on renders of 96–192 pixels, and on larger frames it leaves low-frequency
residue (blotches about its reach wide, colour drifting over large flat surfaces): OIDN's lead over it
at 1 spp grows from 128² to 512². Run on the frame averaged down 2×2, the same network sees 4× the
samples per pixel and twice the scene per receptive field, so its coarse band is cleaner, while its fine
detail is lost. The frame keeps its own detail and takes its band below quarter resolution from the
half-resolution pass (``transfer_low_band``) by a weight w = 1/spp (a low band itself: the mean over the
same blocks, so an adaptive sample map does not print its pixels into the correction): the residue falls
with the samples, the half-resolution pass's own bias does not. BENCHMARKS.md §16: at 1 spp +0.59 dB over 13
scenes at 256² and +1.16 over 6 at 512², at 4 spp +0.08 at 256²; at 128² −0.09 on the mean and −1.8 on
`sun-room`, so frames with a side under LOW_BAND_MIN_SIDE go without. It costs 1.3× the denoiser's GPU
time on lavapipe (a quarter of the work, on a canvas that fills the device less well).

On the device: ``PackHalfDenoiserPass`` (frame/pack.wgsl), the denoiser on that canvas, ``LowBandPass``
(frame/lowband.wgsl); ``transfer_low_band`` and ``pack.pack_half_denoiser_input`` are their references.
"""

from __future__ import annotations

import numpy as np

from ..errors import WgpuRtError
from ..passes import SPP, ComputePass
from .kernel import TILE, FrameKernel, ceil_div, nonnegative_finite
from .pack import block_mean
from .planes import DENOISED

LOW_BAND_EPSILON = 1e-3    # radiance added to both low bands: a black level, so near-black blocks keep F
LOW_BAND_MIN_SIDE = 256    # "auto" takes the low band for frames at least this wide and high
F32_MAX = float(np.finfo(np.float32).max)


def uses_low_band(width: int, height: int, setting=None) -> bool:
    """Whether a width×height frame takes the half-resolution low band: ``setting`` True or False, or
    None (auto: when both sides are at least LOW_BAND_MIN_SIDE)."""
    if setting is None:
        return min(width, height) >= LOW_BAND_MIN_SIDE
    if not isinstance(setting, bool):
        raise WgpuRtError(f"low_band must be True, False or None (auto), got {setting!r}")
    return setting


def bilinear_up(image: np.ndarray, factor: int, shape: tuple[int, int]) -> np.ndarray:
    """(h, w, C) block values → (H, W, C), bilinear between block centres (clamped at the edges), each
    output pixel at ((x + 0.5) / factor − 0.5) in block coordinates."""
    def weights(count: int, blocks: int):
        u = np.clip((np.arange(count) + 0.5) / factor - 0.5, 0.0, blocks - 1)
        first = np.floor(u).astype(np.int64)
        return first, np.minimum(first + 1, blocks - 1), (u - first)

    rows0, rows1, ty = weights(shape[0], image.shape[0])
    cols0, cols1, tx = weights(shape[1], image.shape[1])
    image = np.asarray(image, np.float64)
    top = image[rows0] * (1 - ty[:, None, None]) + image[rows1] * ty[:, None, None]
    return top[:, cols0] * (1 - tx[None, :, None]) + top[:, cols1] * tx[None, :, None]


def transfer_low_band(denoised: np.ndarray, half_denoised: np.ndarray, spp=1) -> np.ndarray:
    """(H, W, 3) denoised radiance F and (ceil(H/2), ceil(W/2), 3) radiance H of the half-resolution pass,
    and the samples per pixel (one count or an (H, W[, 1]) map) → F · (w·LH + (1 − w)·LF + ε) / (LF + ε),
    with LF, LH and w the means of F, H and 1/spp over 4×4 frame pixels, bilinear between block centres
    (float32, finite, ≥ 0)."""
    height, width = denoised.shape[:2]
    full = nonnegative_finite(denoised)
    replicated = np.repeat(np.repeat(nonnegative_finite(half_denoised), 2, axis=0), 2, axis=1)[:height, :width]
    low_full = bilinear_up(block_mean(full, 4), 4, (height, width))
    low_half = bilinear_up(block_mean(replicated, 4), 4, (height, width))
    counts = np.broadcast_to(np.asarray(spp, np.float64).reshape(np.shape(spp)[:2]), (height, width))
    w = bilinear_up(block_mean((1.0 / np.maximum(np.nan_to_num(counts, nan=1.0), 1.0))[..., None], 4), 4,
                    (height, width))
    ratio = np.minimum((w * low_half + (1 - w) * low_full + LOW_BAND_EPSILON) / (low_full + LOW_BAND_EPSILON),
                       F32_MAX)
    return np.minimum(full * ratio, F32_MAX).astype(np.float32)


class LowBandPass(ComputePass):
    """denoised (the full-resolution pass, unpacked), the half-resolution network's output (a buffer given
    to ``execute``), ``half_input`` (PackHalfDenoiserPass's result: the albedo it was demodulated by) and
    spp → denoised, its low band moved towards the half-resolution pass's."""

    inputs = (DENOISED, SPP)
    outputs = (DENOISED,)

    def __init__(self, ctx, width: int, height: int, half_input):
        self.half_input = half_input
        self.quarter = (ceil_div(width, 4), ceil_div(height, 4))
        self.means_buffer = ctx.storage(4 * 7 * self.quarter[0] * self.quarter[1], label="low band means")
        constants = {"EPSILON": LOW_BAND_EPSILON}
        self.means = FrameKernel(ctx, "frame/lowband.wgsl", "low_band_means",
                                 ("denoised", "half_output", "half_input", "means", "spp"), width, height, constants)
        self.apply = FrameKernel(ctx, "frame/lowband.wgsl", "low_band_apply", ("denoised", "means"),
                                 width, height, constants)

    def execute(self, encoder, buffers, half_output) -> None:
        bound = {"denoised": buffers.get(DENOISED), "half_output": half_output, "half_input": self.half_input,
                 "means": self.means_buffer, "spp": buffers.get(SPP)}
        self.means.dispatch(encoder, bound, groups=(ceil_div(self.quarter[0], TILE), ceil_div(self.quarter[1], TILE)))
        self.apply.dispatch(encoder, bound)
