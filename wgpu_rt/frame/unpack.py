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
# The denoiser counts as this many samples when its output is blended with the n-sample mean it
# denoised. Fitted with benchmarks/bench_converge.py (96², 1–128 spp, 8192-spp gold, the shipped
# denoiser): the best constant per scene is 16–32 (cornell, sun-room) and 64–128 (cornell-glossy); 32
# loses least to each row's best (0.20 dB on average). The 1 − 1/√n fade it replaced (≈ k = √n + 1)
# lost to it at every n ≤ 32, at 16 spp by 0.8 dB on cornell and 2.2 dB on cornell-glossy.
CONVERGE_SPP = 32.0


def converge(denoised, samples_mean, spp, converge_spp: float = CONVERGE_SPP) -> np.ndarray:
    """(H, W, 3) denoised frame of an n-sample mean, blended with that mean: its share is
    n / (n + converge_spp) per pixel (``spp`` (H, W))."""
    spp = np.asarray(spp, np.float64)[..., None]
    mean_weight = spp / (spp + converge_spp)
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
        constants = {"CONVERGE": converge_spp is not None, "CONVERGE_SPP": converge_spp or CONVERGE_SPP}
        self.kernel = FrameKernel(ctx, "frame/unpack.wgsl", "main",
                                  ("network_output", "albedo", "radiance", "samples_mean", "spp"), width, height,
                                  constants)

    def execute(self, encoder, buffers, source) -> None:
        source = buffers.get(source) if hasattr(source, "channels") else source
        self.kernel.dispatch(encoder, {"network_output": source, "albedo": buffers.get(ALBEDO),
                                       "radiance": buffers.get(DENOISED), "samples_mean": buffers.get(RADIANCE),
                                       "spp": buffers.get(SPP)})
