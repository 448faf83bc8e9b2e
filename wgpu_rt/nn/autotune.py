"""Convolution kernels chosen per adapter by measurement (``WgslModel(..., autotune=True)``).

For each conv-family layer shape (kernel, channels, stride, pads, input resolution) and precision, every
distinct kernel the conv tilings offer (``none``, ``loop``, ``register``, ``staged``: see
``model.CONV_TILINGS``), each both as one dispatch per layer and, where the layer's weights only fit
uniform bindings window by window, as one dispatch per group of uniform windows (variant suffix
``model.UNIFORM_WINDOWS``; see kernels.WindowLayout), is timed once on this adapter with timestamp
queries, on scratch tensors of the layer's shape, and the fastest variant is remembered in a JSON cache
keyed by (adapter, driver, layer shape, precision): ``$XDG_CACHE_HOME/wgpu-rt/autotune.json``
(``~/.cache/wgpu-rt/autotune.json`` without it). Later models on the same adapter read the choice
instead of measuring.

Off by default: measuring compiles and runs every candidate kernel once per new shape (≈ 23 s for the
shipped denoiser at 256² on lavapipe, where the test suite must not get slower), so it is asked for with
``autotune=True`` or ``WGPU_RT_AUTOTUNE=1``; ``WGPU_RT_AUTOTUNE=0`` turns it off whatever the code asks
(the default tiling and window preference: ``model.default_conv_tiling``,
``model.default_uniform_windows``). A cache file that cannot be read or parsed is ignored and rewritten;
it is written atomically (``wgpu_rt.io.atomic_output``), so a crash never leaves a half file.
"""

from __future__ import annotations

import json
import os
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import wgpu

from ..errors import ModelError
from ..io import atomic_output
from .graph import Layer
from .kernels import Dispatch, TensorView, record_dispatches

ENV = "WGPU_RT_AUTOTUNE"
CACHE_VERSION = 1
TIMED_RUNS = 3  # after one warm-up run; the median counts


def enabled(requested: bool | None) -> bool:
    """Whether to autotune: ``WGPU_RT_AUTOTUNE=0`` never, else ``requested``, else ``WGPU_RT_AUTOTUNE=1``."""
    value = os.environ.get(ENV, "")
    if value not in ("", "0", "1"):
        raise ModelError(f"${ENV}={value!r}: use 1 (measure convolution kernels per adapter) or 0 (never)")
    if value == "0":
        return False
    return requested if requested is not None else value == "1"


def cache_path() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or ""
    return (Path(base) if os.path.isabs(base) else Path.home() / ".cache") / "wgpu-rt" / "autotune.json"


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


class Autotuner:
    """The cache and the measurements. ``timer`` (dispatches -> seconds) defaults to timestamp queries;
    tests pass a fake one. ``measured`` counts the timer's calls in this process."""

    def __init__(self, ctx, path: str | os.PathLike | None = None, timer=None):
        self.ctx = ctx
        self.path = Path(path) if path is not None else cache_path()
        self.timer = timer or (timestamp_timer(ctx) if ctx.has_timestamps else None)
        info = ctx.adapter.info
        self.adapter = " | ".join(str(info.get(k, "")) for k in ("device", "description", "backend_type"))
        self.entries = self._load()
        self.measured = 0

    def _load(self) -> dict:
        """The cache's entries; {} when the file is missing, unreadable or not a cache of this version
        (it is rewritten on the next measurement)."""
        try:
            data = json.loads(self.path.read_text())
            entries = data["entries"] if data.get("version") == CACHE_VERSION else {}
            return {key: value for key, value in entries.items()
                    if isinstance(value, dict) and isinstance(value.get("variant"), str)}
        except (OSError, ValueError, AttributeError, KeyError, TypeError):
            return {}

    def key(self, layer: Layer, src: TensorView, precision: str, pooled: bool = False) -> str:
        """The cache key of ``layer`` reading ``src`` (``pooled``: with a max pool in its epilogue)."""
        cout, cin, kh, kw = layer.weight.shape
        return (f"{self.adapter} | {precision} | {layer.kind}{'+maxpool' * pooled} {cout}x{cin}x{kh}x{kw} "
                f"stride {layer.stride} pads {','.join(map(str, layer.pads))} in {src.height}x{src.width}")

    def choose(self, key: str, candidates: dict[str, Callable[[], list[Dispatch]]], default: str) -> str:
        """The fastest of ``candidates`` (variant -> its dispatches on scratch tensors) for ``key``, from
        the cache or measured now; ``default`` where nothing can be measured (no timestamp queries)."""
        if len(candidates) == 1:
            return next(iter(candidates))
        cached = self.entries.get(key, {}).get("variant")
        if cached in candidates:
            return cached
        if self.timer is None:
            return default
        seconds = {}
        for variant, dispatches in candidates.items():
            seconds[variant] = self.timer(dispatches())
            self.measured += 1
        best = min(seconds, key=seconds.get)
        self.entries[key] = {"variant": best, "seconds": seconds}
        self._save(key)
        return best

    def _save(self, key: str) -> None:
        """Add ``key`` to what is on disk now (another process may have added entries) and replace the
        file atomically."""
        entries = self._load()
        entries[key] = self.entries[key]
        self.entries.update(entries)
        try:
            with atomic_output(self.path) as tmp:
                tmp.write_text(json.dumps({"version": CACHE_VERSION, "entries": entries}, indent=1,
                                          sort_keys=True))
        except OSError as err:  # a cache that cannot be written costs a measurement next time, not the run
            warnings.warn(f"autotune cache not saved: {err}", stacklevel=2)
