"""Planar planes → (H, W, C) order on the device before they are read back (wgsl/frame/interleave.wgsl),
so that the host copies a frame's HDR colour out in one contiguous copy: at 1080p the strided per-channel
copy of 25 MB was most of what a frame cost the host beyond its GPU time (BENCHMARKS.md §21)."""

from __future__ import annotations

import numpy as np

from ..passes import ComputePass, PlaneSpec
from .kernel import FrameKernel


def interleaved(values: np.ndarray, height: int, width: int) -> np.ndarray:
    """Planar channels (C·H·W values, any dtype) → a new (H, W, C) float32 array, one channel at a time
    (a strided copy of the whole (C, H, W) view is about twice as slow). The numpy reference of
    ``InterleavePass``, and the host's way for the planes it leaves (integer and single-channel ones)."""
    channels = values.size // (height * width)
    out = np.empty((height, width, channels), np.float32)
    for channel in range(channels):
        out[..., channel] = values[channel * height * width:(channel + 1) * height * width].reshape(height, width)
    return out


def interleaves(plane: PlaneSpec) -> bool:
    """Whether ``plane`` is rewritten on the device before its readback: f32 planes of several channels."""
    return plane.dtype == "f32" and plane.channels > 1


class InterleavePass(ComputePass):
    """``plane`` → ``self.result``, a buffer of its values in (H, W, C) order."""

    def __init__(self, ctx, width: int, height: int, plane: PlaneSpec):
        self.plane, self.inputs = plane, (plane,)
        self.kernel = FrameKernel(ctx, "frame/interleave.wgsl", "main", ("planar", "interleaved"), width, height,
                                  constants={"CHANNELS": plane.channels})
        self.result = ctx.storage(plane.nbytes(width, height), label=f"{plane.name}, interleaved")

    def execute(self, encoder, buffers) -> None:
        self.kernel.dispatch(encoder, {"planar": buffers.get(self.plane), "interleaved": self.result})
