"""The one dispatch helper every frame pass uses: a WGSL entry point run once per pixel.

Frame kernels are specialised by WGSL ``override`` constants (frame size and each pass's settings)
rather than uniform buffers, so that recording a frame uploads nothing: the only host↔device traffic
of a frame is the tracer's own parameters and the final readback. Each kernel runs 8×8 workgroups
over the image (``WORKGROUP`` in ``frame/common.wgsl``), so a 4K frame stays under the 65535
workgroups-per-dimension limit.
"""

from __future__ import annotations

import re

import numpy as np

from ..shaders import compose

TILE = 8
_BINDING = re.compile(r"@group\(0\)\s*@binding\((\d+)\)\s*var(?:<[^>]*>)?\s+(\w+)")


def binding_names(code: str) -> dict[str, int]:
    """Binding index of every ``@group(0)`` variable a WGSL module declares, by name."""
    return {name: int(index) for index, name in _BINDING.findall(code)}


def ceil_div(a: int, b: int) -> int:
    return -(-a // b)


def gaussian_taps(sigma: float, radius: int) -> np.ndarray:
    """The 2·radius + 1 normalised weights of a Gaussian of ``sigma`` (float64)."""
    offsets = np.arange(-radius, radius + 1)
    taps = np.exp(-offsets * offsets / (2.0 * sigma ** 2))
    return taps / taps.sum()


def separable_blur(image: np.ndarray, taps: np.ndarray) -> np.ndarray:
    """(h, w, C) values weighed by ``taps`` along both axes, indices clamped at the edges (float64)."""
    radius = len(taps) // 2
    out = np.asarray(image, np.float64)
    for axis in (0, 1):
        padded = np.pad(out, [(radius, radius) if a == axis else (0, 0) for a in range(3)], mode="edge")
        length = out.shape[axis]
        out = sum(tap * np.take(padded, np.arange(k, k + length), axis=axis) for k, tap in enumerate(taps))
    return out


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
    """One entry point of a ``wgsl/frame/*.wgsl`` shader, specialised for a width×height frame.

    ``uses`` names the bindings this entry point reads or writes (WebGPU's automatic layout leaves the
    others out); their indices are read from the shader's own ``@group(0) @binding(i) var… name``
    declarations, so a binding's place is declared once, in the WGSL. ``dispatch`` takes a dict of
    buffers by name (extra names are ignored, so one dict can serve every entry point of a shader),
    caches the bind group and records one dispatch over the frame's pixels (or ``groups`` workgroups).
    """

    def __init__(self, ctx, shader: str, entry: str, uses: tuple[str, ...], width: int, height: int,
                 constants: dict | None = None):
        code = compose(shader)
        declared = binding_names(code)
        unknown = [name for name in uses if name not in declared]
        if unknown:
            raise ValueError(f"{shader}: no @group(0) binding named {unknown} (declared: {sorted(declared)})")
        self.ctx, self.entry = ctx, entry
        self.bindings = [name if name in uses else None for name in
                         (next((n for n, i in declared.items() if i == index), None)
                          for index in range(max(declared[n] for n in uses) + 1))]
        self.width, self.height = width, height
        self.pipeline = ctx.compute_pipeline(
            code, entry_point=entry, label=f"{shader}:{entry}",
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
