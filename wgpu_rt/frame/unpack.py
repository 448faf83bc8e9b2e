"""The denoiser's output back to linear radiance: expm1 of its log1p irradiance (clamped to [0, 88],
NaN → 0), remodulated by the frame's albedo factor (pack.albedo_factor, the one the input was divided by);
for a frame of several samples per pixel, blended with their mean (``converge``)."""

from __future__ import annotations

import numpy as np

from ..passes import ALBEDO, RADIANCE, SPP, ComputePass
from .kernel import FrameKernel, finite, nonnegative_finite
from .pack import albedo_factor
from .planes import DENOISED

MAX_LOG_RADIANCE = 88.0   # expm1(88) ≈ 1.65e38: times the factor (≤ 1.01) still a finite f32
# The denoiser counts as k = max(CONVERGE_SPP, CONVERGE_SCALE / n) samples when its output is blended
# with the n-sample mean it denoised. Fitted with benchmarks/bench_converge.py for the spp-aware
# denoiser (64², 4–256 spp, 4096-spp gold; cornell, cornell-glossy, sun-room and three held-out worlds,
# checked on four other held-out worlds; BENCHMARKS.md §7): the best constant k per row ranges from 32
# (cornell, sun-room at any n) to 2048 (worlds with fireflies at 4–16 spp, whose mean would bring them
# in); this rule, 512 at 4 spp, 128 at 16 and 32 from 64 on, loses 1.24 dB to each row's best against
# 1.69 for k = 32 alone, with the same worst row against brute force. (The constant 32 was fitted for
# the previous, 1-spp denoiser.)
CONVERGE_SPP = 32.0
CONVERGE_SCALE = 2048.0


def converge(denoised, samples_mean, spp, converge_spp: float = CONVERGE_SPP,
             converge_scale: float = CONVERGE_SCALE) -> np.ndarray:
    """(H, W, 3) denoised frame of an n-sample mean, blended with that mean: its share is
    n / (n + max(converge_spp, converge_scale / n)) per pixel (``spp`` (H, W); 0 counts as 1)."""
    spp = np.maximum(np.asarray(spp, np.float64), 1.0)[..., None]
    mean_weight = spp / (spp + np.maximum(converge_spp, converge_scale / spp))
    denoised = nonnegative_finite(denoised).astype(np.float64)
    return (denoised + mean_weight * (nonnegative_finite(samples_mean) - denoised)).astype(np.float32)


def unpack_denoiser_output(output: np.ndarray, albedo: np.ndarray) -> np.ndarray:
    """(3, H, W) network output (log1p irradiance) and (H, W, 3) albedo → (H, W, 3) linear radiance,
    finite and ≥ 0."""
    log_irradiance = np.clip(finite(output), 0.0, MAX_LOG_RADIANCE)
    return (np.expm1(log_irradiance) * albedo_factor(albedo)).transpose(1, 2, 0).astype(np.float32)


class UnpackPass(ComputePass):
    """The network's output (a buffer, or a plane, given to each execute) and albedo → denoised (3 planes);
    with ``converge_spp``, blended with the traced sample mean (radiance, spp) by ``converge``."""

    inputs = (ALBEDO, RADIANCE, SPP)
    outputs = (DENOISED,)

    def __init__(self, ctx, width: int, height: int, converge_spp: float | None = None):
        constants = {"CONVERGE": converge_spp is not None, "CONVERGE_SPP": converge_spp or CONVERGE_SPP,
                     "CONVERGE_SCALE": CONVERGE_SCALE}
        self.kernel = FrameKernel(ctx, "frame/unpack.wgsl", "main",
                                  ("network_output", "albedo", "radiance", "samples_mean", "spp"), width, height,
                                  constants)

    def execute(self, encoder, buffers, source) -> None:
        source = buffers.get(source) if hasattr(source, "channels") else source
        self.kernel.dispatch(encoder, {"network_output": source, "albedo": buffers.get(ALBEDO),
                                       "radiance": buffers.get(DENOISED), "samples_mean": buffers.get(RADIANCE),
                                       "spp": buffers.get(SPP)})
