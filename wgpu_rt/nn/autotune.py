"""Convolution kernels chosen per adapter by measurement (``WgslModel(..., autotune=True)``).

For each conv-family layer shape (kernel, channels, stride, pads, input resolution) and precision, every
distinct kernel the conv tilings offer (``none``, ``loop``, ``register``, ``staged``: see
``model.CONV_TILINGS``), each both as one dispatch per layer and, where the layer's weights only fit
uniform bindings window by window, as one dispatch per group of uniform windows (variant suffix
``model.UNIFORM_WINDOWS``; see kernels.WindowLayout), is timed once on this adapter with timestamp
queries, on scratch tensors of the layer's shape, and the fastest variant is remembered in a JSON cache
keyed by (adapter, driver, layer shape, precision) (wgpu_rt.measured_choices: the cache and its file).
Later models on the same adapter read the choice instead of measuring.

Off by default: measuring compiles and runs every candidate kernel once per new shape (≈ 23 s for the
shipped denoiser at 256² on lavapipe, where the test suite must not get slower), so it is asked for with
``autotune=True`` or ``WGPU_RT_AUTOTUNE=1``; ``WGPU_RT_AUTOTUNE=0`` turns it off whatever the code asks
(the default tiling and window preference: ``model.default_conv_tiling``,
``model.default_uniform_windows``).
"""

from __future__ import annotations

import os
from collections.abc import Callable

import numpy as np
import wgpu

from ..errors import ModelError
from ..measured_choices import MeasuredChoices, cache_path  # noqa: F401 (cache_path: the cache the choices share)
from .graph import Layer
from .kernels import Dispatch, TensorView, record_dispatches

ENV = "WGPU_RT_AUTOTUNE"
TIMED_RUNS = 3  # after one warm-up run; the median counts


def enabled(requested: bool | None) -> bool:
    """Whether to autotune: ``WGPU_RT_AUTOTUNE=0`` never, else ``requested``, else ``WGPU_RT_AUTOTUNE=1``."""
    value = os.environ.get(ENV, "")
    if value not in ("", "0", "1"):
        raise ModelError(f"${ENV}={value!r}: use 1 (measure convolution kernels per adapter) or 0 (never)")
    if value == "0":
        return False
    return requested if requested is not None else value == "1"


def timestamp_timer(ctx) -> Callable[[list[Dispatch]], float]:
    """GPU seconds of a list of dispatches: timestamps around each, summed; median of TIMED_RUNS runs
    after a warm-up."""

    def seconds(dispatches: list[Dispatch]) -> float:
        count = 2 * len(dispatches)
        query_set = ctx.device.create_query_set(type=wgpu.QueryType.timestamp, count=count)
        resolved = ctx.storage(8 * count, label="autotune timestamps", usage=wgpu.BufferUsage.QUERY_RESOLVE)
        runs = []
        for _ in range(TIMED_RUNS + 1):
            encoder = ctx.device.create_command_encoder(label="wgpu-rt autotune")
            record_dispatches(encoder, dispatches, query_set)
            encoder.resolve_query_set(query_set, 0, count, resolved, 0)
            ctx.device.queue.submit([encoder.finish()])
            stamps = ctx.read(resolved, np.uint64, (len(dispatches), 2)).astype(np.int64)
            runs.append(float(np.maximum(stamps[:, 1] - stamps[:, 0], 0).sum()) * 1e-9)
        return float(np.median(runs[1:]))

    return seconds


class Autotuner(MeasuredChoices):
    """The conv kernels' choices: timed with timestamp queries unless ``timer`` (dispatches -> seconds)
    is given (tests pass a fake one)."""

    def __init__(self, ctx, path: str | os.PathLike | None = None, timer=None):
        super().__init__(ctx, path, timer or (timestamp_timer(ctx) if ctx.has_timestamps else None))

    def key(self, layer: Layer, src: TensorView, precision: str, pooled: bool = False) -> str:
        """The cache key of ``layer`` reading ``src`` (``pooled``: with a max pool in its epilogue)."""
        cout, cin, kh, kw = layer.weight.shape
        return (f"{self.adapter} | {precision} | {layer.kind}{'+maxpool' * pooled} {cout}x{cin}x{kh}x{kw} "
                f"stride {layer.stride} pads {','.join(map(str, layer.pads))} in {src.height}x{src.width}")
