"""Per-dispatch GPU time of a ``WgslModel`` from timestamp queries (``wgpu-rt profile``).

Every run records the inference twice in one command buffer: once with each dispatch in its own
timestamped compute pass (``WgslModel.record(..., query_set=...)``: the per-dispatch times), then as an
inference normally runs (one compute pass) between two empty passes that write a timestamp each (the
end-to-end time, which the per-dispatch sum exceeds by the pass boundaries it adds). Times are the
median over the runs that follow untimed warm-up runs (at least one, and WARM_UP_SECONDS of them).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np
import wgpu

from ..errors import DeviceLimitError

WARM_UP_SECONDS = 0.5


@dataclass
class DispatchTime:
    """One dispatch of the inference and its median GPU time."""

    index: int
    band: int                          # which band of rows (0 unless the frame runs in bands)
    label: str                         # the ONNX node (and output-block group), or pack/unpack
    kernel: str
    output: tuple[int, int, int]       # C, H, W written by this dispatch
    workgroups: tuple[int, int, int]
    flops: int
    seconds: float

    @property
    def workgroup_count(self) -> int:
        return int(np.prod(self.workgroups))

    @property
    def flops_per_second(self) -> float | None:
        """None where nothing was computed or the time is below the timer's resolution."""
        return self.flops / self.seconds if self.flops and self.seconds > 0 else None


@dataclass
class Profile:
    model: str
    adapter: str
    precision: str
    conv_tiling: str
    weight_fetch: str
    math: str
    size: tuple[int, int]              # width, height of the input
    canvas: tuple[int, int]            # width, height of one pass of the network: padded to its pooling
    bands: int                         # multiple, and a band's rows when the frame runs in bands
    repeat: int
    network_flops: int                 # one pass over the whole frame (Plan.flops)
    end_to_end_seconds: float
    rows: list[DispatchTime]

    @property
    def dispatch_seconds(self) -> float:
        return sum(row.seconds for row in self.rows)

    def as_dict(self) -> dict:
        rows = [{**asdict(row), "workgroup_count": row.workgroup_count,
                 "flops_per_second": row.flops_per_second} for row in self.rows]
        return {"model": self.model, "adapter": self.adapter, "precision": self.precision,
                "conv_tiling": self.conv_tiling, "weight_fetch": self.weight_fetch, "math": self.math,
                "size": list(self.size), "canvas": list(self.canvas), "bands": self.bands,
                "repeat": self.repeat, "dispatch_count": len(self.rows), "network_flops": self.network_flops,
                "dispatch_flops": sum(row.flops for row in self.rows),
                "dispatch_seconds": self.dispatch_seconds, "end_to_end_seconds": self.end_to_end_seconds,
                "rows": rows}


def profile(model, height: int, width: int, repeat: int = 5, seed: int = 0) -> Profile:
    """Time every dispatch of ``model`` (a ``WgslModel`` of one pass: no ensemble) at height×width on
    uniform [0, 1) input."""
    if model.ensemble != 1:
        raise ValueError(f"profile one pass of the network: {model.path} runs an ensemble of {model.ensemble}")
    ctx = model.ctx
    if not ctx.has_timestamps:
        raise DeviceLimitError(f"profiling needs the timestamp-query feature, which {ctx.label} lacks")
    plan = model.plan(height, width)
    x = np.random.default_rng(seed).uniform(0, 1, (model.input_channels, height, width)).astype(np.float32)
    input_buffer = ctx.upload(x, label="profile input")
    dispatches = model.dispatches(height, width, input_buffer)
    count = 2 * len(dispatches) + 2  # begin and end of every dispatch, then of the whole inference
    query_set = ctx.device.create_query_set(type=wgpu.QueryType.timestamp, count=count)
    resolved = ctx.storage(8 * count, label="profile timestamps", usage=wgpu.BufferUsage.QUERY_RESOLVE)

    def mark(encoder, index: int) -> None:
        encoder.begin_compute_pass(label="profile mark", timestamp_writes={
            "query_set": query_set, "beginning_of_pass_write_index": index}).end()

    def run() -> np.ndarray:
        encoder = ctx.device.create_command_encoder(label="wgpu-rt profile")
        model.record(encoder, input_buffer, height, width, query_set=query_set)
        mark(encoder, count - 2)
        model.record(encoder, input_buffer, height, width)
        mark(encoder, count - 1)
        encoder.resolve_query_set(query_set, 0, count, resolved, 0)
        ctx.device.queue.submit([encoder.finish()])
        stamps = ctx.read(resolved, np.uint64, (count // 2, 2)).astype(np.int64)
        # WebGPU does not promise monotonic timestamps across passes: a reversed pair counts as 0
        return np.maximum(stamps[:, 1] - stamps[:, 0], 0) * 1e-9

    # warm-up: the first use of every pipeline and buffer, then runs for WARM_UP_SECONDS, so that a GPU
    # whose clocks dropped while it waited (or through the autotuner's short bursts: on an H200 every layer
    # of a profile right after autotuning ran ~3.7x slower than the same kernels otherwise, BENCHMARKS.md
    # §21) is timed at speed
    started = time.perf_counter()
    run()
    while time.perf_counter() - started < WARM_UP_SECONDS:
        run()
    seconds = np.median([run() for _ in range(repeat)], axis=0)
    per_band = len(dispatches) // len(plan.bands)
    rows = [DispatchTime(index, index // per_band, d.label, d.kernel, d.output, d.workgroups, d.flops,
                         float(seconds[index])) for index, d in enumerate(dispatches)]
    tiling, fetch, math = (("autotuned",) * 3 if model.autotuner
                           else (model.conv_tiling, model.weight_fetch, model.math))
    if math != "f32" and fetch != "direct":
        fetch += " (direct in the f16 3×3 kernels)"
    return Profile(model.path, ctx.label, model.precision.name, tiling, fetch, math, (width, height),
                   plan.canvas[::-1],
                   len(plan.bands), repeat, plan.flops, float(seconds[-1]), rows)
