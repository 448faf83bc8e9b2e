"""The denoiser's output back to linear radiance: expm1 of its log1p irradiance (clamped to [0, 43],
NaN → 0), remodulated by the frame's albedo factor (pack.albedo_factor, the one the input was divided by)."""

from __future__ import annotations

import numpy as np

from ..passes import ALBEDO, ComputePass
from .kernel import FrameKernel, finite
from .pack import albedo_factor
from .planes import DENOISED

MAX_LOG_RADIANCE = 43.0   # expm1(43) ≈ 4.7e18: times the factor (≤ 1.01 × 3, the largest white-balance gain,
                          # × 2^64, the largest exposure scale) still a finite f32


def unpack_denoiser_output(output: np.ndarray, albedo: np.ndarray, balance: np.ndarray) -> np.ndarray:
    """(3, H, W) network output (log1p irradiance), (H, W, 3) albedo and the white-balance gains the input
    was packed with (pack.white_balance_gains) → (H, W, 3) linear radiance, finite and ≥ 0."""
    log_irradiance = np.clip(finite(output), 0.0, MAX_LOG_RADIANCE)
    return (np.expm1(log_irradiance) * albedo_factor(albedo, balance)).transpose(1, 2, 0).astype(np.float32)


class UnpackPass(ComputePass):
    """The network's output (a buffer, or a plane, given to each execute) and albedo → denoised (3 planes).
    ``albedo_plane`` 3: the albedo comes from the denoiser's packed input instead (planes 3–5), for a
    coarser level's canvas (frame/lowband.py), written by ``unpack``. ``balance``: the white-balance gains
    the input was packed with (pack.WhiteBalancePass's result)."""

    inputs = (ALBEDO,)
    outputs = (DENOISED,)

    def __init__(self, ctx, width: int, height: int, balance, albedo_plane: int = 0):
        self.balance = balance
        self.kernel = FrameKernel(ctx, "frame/unpack.wgsl", "main", ("network_output", "albedo", "radiance", "balance"),
                                  width, height, constants={"ALBEDO_PLANE": albedo_plane})

    def execute(self, encoder, buffers, source) -> None:
        source = buffers.get(source) if hasattr(source, "channels") else source
        self.unpack(encoder, source, buffers.get(ALBEDO), buffers.get(DENOISED))

    def unpack(self, encoder, network_output, albedo, radiance) -> None:
        self.kernel.dispatch(encoder, {"network_output": network_output, "albedo": albedo, "radiance": radiance,
                                       "balance": self.balance})
