"""The render-pass contract (after Falcor's render passes).

A pass is one unit of GPU work. It declares the planar buffers it reads and writes (name, channels,
element type) and records its dispatches into a command encoder it is handed; it never submits or
reads back. A pipeline owns the buffers (``FrameBuffers``), wires passes by buffer name and records a
whole frame into one encoder, so data stays on the device between passes.

Planar layout: a buffer of C channels for a W×H frame holds C planes of W·H values, channel-major,
which is NCHW with N=1: the tracer's outputs are already almost the networks' input.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

DTYPE_BYTES = {"f32": 4, "u32": 4, "f16": 2}
NUMPY_DTYPE = {"f32": np.float32, "u32": np.uint32, "f16": np.float16}


@dataclass(frozen=True)
class PlaneSpec:
    """A planar per-pixel buffer: ``channels`` planes of ``dtype`` over the frame's pixels."""

    name: str
    channels: int
    dtype: str = "f32"

    def nbytes(self, width: int, height: int) -> int:
        return self.channels * width * height * DTYPE_BYTES[self.dtype]


# The tracer's outputs, which the frame passes read (ARCHITECTURE.md, "Planar buffers").
RADIANCE = PlaneSpec("radiance", 3)
ALBEDO = PlaneSpec("albedo", 3)
NORMAL = PlaneSpec("normal", 3)
DEPTH = PlaneSpec("depth", 1)
MOTION = PlaneSpec("motion", 2)
SPP = PlaneSpec("spp", 1, "u32")


@dataclass(frozen=True)
class Stage:
    """A step of the frame that is not a ComputePass (a network, a copy), as far as wiring goes
    (frame.pipeline.check_wiring)."""

    name: str
    inputs: tuple[PlaneSpec, ...]
    outputs: tuple[PlaneSpec, ...]


class ComputePass(ABC):
    """Base class: subclasses set ``inputs``/``outputs`` (the planes they read and write, by which a
    pipeline wires them) and implement ``execute``."""

    inputs: tuple[PlaneSpec, ...] = ()
    outputs: tuple[PlaneSpec, ...] = ()

    @abstractmethod
    def execute(self, encoder, buffers: "FrameBuffers", **per_frame) -> None:
        """Record this pass's dispatches into ``encoder``, reading and writing ``buffers``; what changes
        from frame to frame (a sample schedule, a network's output, how the frame moved) comes as
        keyword arguments, never as attributes set on the pass beforehand."""


class FrameBuffers:
    """Named planar storage buffers for one frame size, allocated on first request."""

    def __init__(self, ctx, width: int, height: int):
        self.ctx, self.width, self.height = ctx, width, height
        self._buffers: dict[str, tuple[PlaneSpec, object]] = {}

    def get(self, spec: PlaneSpec):
        """The buffer for ``spec``, allocating it the first time; a clash of specs is an error."""
        held = self._buffers.get(spec.name)
        if held is None:
            buffer = self.ctx.storage(spec.nbytes(self.width, self.height), label=spec.name)
            self._buffers[spec.name] = (spec, buffer)
            return buffer
        if held[0] != spec:
            raise ValueError(f"buffer {spec.name!r} requested as {spec} but allocated as {held[0]}")
        return held[1]

    def __getitem__(self, name: str):
        return self._buffers[name][1]

    def __contains__(self, name: str) -> bool:
        return name in self._buffers

    def read(self, name: str) -> np.ndarray:
        """Read one buffer back as a (channels, height, width) array (tests and the final image only)."""
        spec, buffer = self._buffers[name]
        shape = (spec.channels, self.height, self.width)
        return self.ctx.read(buffer, NUMPY_DTYPE[spec.dtype], shape)


def prepare_network(network, input_buffer, height: int, width: int) -> None:
    """Have ``network`` build ahead what its first ``record`` from ``input_buffer`` at height×width would
    (``WgslModel.prepare``); a network without ``prepare`` (a test's stand-in) builds nothing ahead."""
    prepare = getattr(network, "prepare", None)
    if prepare is not None:
        prepare(input_buffer, height, width)
