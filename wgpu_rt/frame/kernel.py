"""The one dispatch helper every frame pass uses: a WGSL entry point run once per pixel.

Frame kernels are specialised by WGSL ``override`` constants (frame size and each pass's settings)
rather than uniform buffers, so that recording a frame uploads nothing: the only host↔device traffic
of a frame is the tracer's own parameters and the final readback. Each kernel runs 8×8 workgroups
over the image (``WORKGROUP`` in ``frame/common.wgsl``), so a 4K frame stays under the 65535
workgroups-per-dimension limit.
"""

from __future__ import annotations

import numpy as np

from ..shaders import compose

TILE = 8


def ceil_div(a: int, b: int) -> int:
    return -(-a // b)


def nonnegative_finite(values: np.ndarray) -> np.ndarray:
    """``values`` as float32 with NaN/±Inf replaced by 0 and negatives clamped to 0 (the sanitising rule
    shared by every frame pass: a non-finite sample is a failed sample, not a bright one)."""
    values = np.asarray(values, dtype=np.float32)
    return np.where(np.isfinite(values), np.maximum(values, 0.0), 0.0).astype(np.float32)


def finite(values: np.ndarray) -> np.ndarray:
    """``values`` as float32 with NaN/±Inf replaced by 0 (sign kept, for normals)."""
    values = np.asarray(values, dtype=np.float32)
    return np.where(np.isfinite(values), values, 0.0).astype(np.float32)


class FrameKernel:
    """One entry point of a ``wgsl/frame_*.wgsl`` shader, specialised for a width×height frame.

    ``bindings`` names the shader's bindings 0, 1, … in order, with None for a binding this entry point
    does not use (WebGPU's automatic layout leaves those out). ``dispatch`` takes a dict of buffers by
    name (extra names are ignored, so one dict can serve every entry point of a shader), caches the bind
    group and records one dispatch over the frame's pixels (or ``groups`` workgroups).
    """

    def __init__(self, ctx, shader: str, entry: str, bindings: tuple[str, ...], width: int, height: int,
                 constants: dict | None = None):
        self.ctx, self.entry, self.bindings = ctx, entry, bindings
        self.width, self.height = width, height
        self.pipeline = ctx.compute_pipeline(
            compose(shader), entry_point=entry, label=f"{shader}:{entry}",
            constants={"WIDTH": width, "HEIGHT": height, **(constants or {})})
        self._bind_groups: dict[tuple, object] = {}

    def bind_group(self, buffers: dict):
        missing = [name for name in self.bindings if name is not None and buffers.get(name) is None]
        if missing:
            raise KeyError(f"{self.entry}: no buffer given for binding(s) {missing}")
        ordered = [None if name is None else buffers[name] for name in self.bindings]
        key = tuple(id(b) for b in ordered)
        group = self._bind_groups.get(key)
        if group is None:
            group = self._bind_groups[key] = self.ctx.bind_group(self.pipeline, ordered)
        return group

    def record(self, compute_pass, buffers: dict, groups: tuple[int, int] | None = None) -> None:
        """Record the dispatch into an open ``compute_pass``."""
        compute_pass.set_pipeline(self.pipeline)
        compute_pass.set_bind_group(0, self.bind_group(buffers))
        compute_pass.dispatch_workgroups(*(groups or self.pixel_groups), 1)

    def record_indirect(self, compute_pass, buffers: dict, arguments, offset: int) -> None:
        """Record a dispatch whose workgroup counts a kernel wrote at ``offset`` of ``arguments``."""
        compute_pass.set_pipeline(self.pipeline)
        compute_pass.set_bind_group(0, self.bind_group(buffers))
        compute_pass.dispatch_workgroups_indirect(arguments, offset)

    def dispatch(self, encoder, buffers: dict, groups: tuple[int, int] | None = None) -> None:
        """Record the dispatch in a compute pass of its own on ``encoder``."""
        compute_pass = encoder.begin_compute_pass(label=self.entry)
        self.record(compute_pass, buffers, groups)
        compute_pass.end()

    @property
    def pixel_groups(self) -> tuple[int, int]:
        return ceil_div(self.width, TILE), ceil_div(self.height, TILE)
