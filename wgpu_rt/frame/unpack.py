"""The denoiser's log1p output back to linear radiance (expm1, clamped ≥ 0, NaN → 0)."""

from __future__ import annotations

import numpy as np

from ..render_pass import ComputePass
from .kernel import FrameKernel, finite
from .planes import DENOISED

MAX_LOG_RADIANCE = 88.0   # expm1(88) ≈ 1.65e38: the largest log value whose expm1 is a finite f32


def unpack_denoiser_output(output: np.ndarray) -> np.ndarray:
    """(3, H, W) network output (log1p RGB) → (H, W, 3) linear radiance, finite and ≥ 0."""
    log_radiance = np.clip(finite(output), 0.0, MAX_LOG_RADIANCE)
    return np.expm1(log_radiance).transpose(1, 2, 0).astype(np.float32)


class UnpackPass(ComputePass):
    """``source`` (the network's output buffer, or a plane) → denoised (3 planes)."""

    outputs = (DENOISED,)

    def __init__(self, ctx, width: int, height: int, source=None):
        self.source = source
        self.kernel = FrameKernel(ctx, "frame_unpack.wgsl", "main", ("network_output", "radiance"),
                                  width, height)

    def execute(self, encoder, buffers) -> None:
        source = buffers.get(self.source) if hasattr(self.source, "channels") else self.source
        self.kernel.dispatch(encoder, {"network_output": source, "radiance": buffers.get(DENOISED)})
