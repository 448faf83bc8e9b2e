"""U-Net inference: the WGSL engine (naive → tiled → fp16 steps) against onnxruntime CPU, same run.

For each size it prints ms per frame (wall clock, best run) and CPU seconds per frame (this process's
threads, lavapipe's workers included: on a shared machine this is the stable number, and the ratio
column compares it), GFLOP/s of the whole network (per wall second) and of the conv kernels alone
(timestamp queries around every dispatch, best of the repeats), that rate as a percent of the adapter's
FMA ceiling (measured here with benchmarks/fma_peak.wgsl before the steps and after each, the highest
reading counting), the planned peak activation memory, and the ratio to onnxruntime's
time (intra-op threads = CPU cores). Steps: ``naive`` = one output pixel per invocation,
``loop-tiled`` = 4-pixel tiles in loops, ``reg-tiled`` = plus conv3x3.wgsl's written-out 4-pixel ×
32-channel tile (16 where the output is not 32k channels; the default on CPU and integrated adapters),
``staged`` = the 16-channel tile with its input staged in workgroup memory (conv3x3_staged.wgsl, the
default on discrete GPUs), ``fp16`` = the adapter's default tiling with f16 activations, ``autotuned`` = the
tiling of every layer measured on this adapter (wgpu_rt.nn.autotune: the first run on an adapter times the
candidates, before the timed frames, and caches the choice in the user's cache folder). Every step runs
the same 2×2 transposed-convolution kernel (conv_transpose.wgsl, 4 input pixels per invocation) and its
dispatches count as conv dispatches.

    python3 benchmarks/bench_nn.py --sizes 256 512            # add 1080p for the full-HD run (slow)
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SIZES = {"256": (256, 256), "512": (512, 512), "1080p": (1080, 1920)}
STEPS = {"naive": {"precision": "fp32", "conv_tiling": "none"},
         "loop-tiled": {"precision": "fp32", "conv_tiling": "loop"},
         "reg-tiled": {"precision": "fp32", "conv_tiling": "register"},
         "staged": {"precision": "fp32", "conv_tiling": "staged"},
         "fp16": {"precision": "fp16", "conv_tiling": None},
         "autotuned": {"precision": "fp32", "conv_tiling": None, "autotune": True}}


def fma_ceiling(ctx, iterations: int = 4096, invocations: int = 64 * 512) -> float:
    """GFLOP/s of the FMA loop kernel (best of 3)."""
    from wgpu_rt import shaders

    pipeline = ctx.compute_pipeline(shaders.compose("fma_peak.wgsl", Path(__file__).parent,
                                                    {"ITERATIONS": iterations}))
    sink = ctx.storage(invocations * 16)
    bind_group = ctx.bind_group(pipeline, [sink])
    best = float("inf")
    for _ in range(4):
        encoder = ctx.device.create_command_encoder()
        compute = encoder.begin_compute_pass()
        compute.set_pipeline(pipeline)
        compute.set_bind_group(0, bind_group)
        compute.dispatch_workgroups(invocations // 64)
        compute.end()
        start = time.perf_counter()
        ctx.device.queue.submit([encoder.finish()])
        ctx.read(sink, nbytes=16)
        best = min(best, time.perf_counter() - start)
    return invocations * iterations * 4 * 4 * 2 / best / 1e9


def timed(run, repeats: int) -> tuple[float, float]:
    """(best wall seconds, best CPU seconds of this process) over ``repeats`` calls of ``run``."""
    walls, cpus = [], []
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        run()
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    return min(walls), min(cpus)


def time_onnxruntime(path: Path, x: np.ndarray, repeats: int) -> tuple[float, float]:
    import onnxruntime as ort

    options = ort.SessionOptions()
    options.intra_op_num_threads = os.cpu_count()
    session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    session.run(None, {"input": x})
    return timed(lambda: session.run(None, {"input": x}), repeats)


def time_engine(model, x: np.ndarray, repeats: int) -> tuple[float, float, float, int]:
    """(best wall and CPU seconds per frame, seconds spent in conv-family dispatches, their FLOPs)."""
    import wgpu

    ctx = model.ctx
    _, _, height, width = x.shape
    input_buffer = ctx.upload(x, label="bench input")
    model(x)  # builds the plan and compiles the pipelines

    def frame():
        encoder = ctx.device.create_command_encoder()
        output = model.record(encoder, input_buffer, height, width)
        ctx.device.queue.submit([encoder.finish()])
        ctx.read(output, nbytes=16)

    wall, cpu = timed(frame, repeats)
    dispatches = model.dispatches(height, width, input_buffer)
    query_set = ctx.device.create_query_set(type=wgpu.QueryType.timestamp, count=2 * len(dispatches))
    resolved = ctx.storage(16 * len(dispatches), usage=wgpu.BufferUsage.QUERY_RESOLVE)
    conv = [i for i, d in enumerate(dispatches) if d.flops]
    conv_seconds = float("inf")
    for _ in range(repeats):  # best of the repeats, like the wall and CPU times
        encoder = ctx.device.create_command_encoder()
        model.record(encoder, input_buffer, height, width, query_set=query_set)
        encoder.resolve_query_set(query_set, 0, 2 * len(dispatches), resolved, 0)
        ctx.device.queue.submit([encoder.finish()])
        stamps = ctx.read(resolved, np.uint64).reshape(-1, 2)
        conv_seconds = min(conv_seconds, float(sum(stamps[i, 1] - stamps[i, 0] for i in conv)) * 1e-9)
    return wall, cpu, conv_seconds, sum(dispatches[i].flops for i in conv)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", nargs="+", default=["256", "512"], choices=list(SIZES))
    parser.add_argument("--steps", nargs="+", default=list(STEPS), choices=list(STEPS))
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    import torch

    from wgpu_rt.errors import WgpuRtError
    from wgpu_rt.gpu import get_context
    from wgpu_rt.train.networks import UNet, export_onnx
    from wgpu_rt.nn import WgslModel

    ctx = get_context()
    torch.manual_seed(args.seed)
    path = export_onnx(UNet(), Path(tempfile.mkdtemp()) / "unet.onnx")
    print(f"adapter: {ctx.label}   CPU cores: {os.cpu_count()}")
    models = {step: WgslModel(path, ctx=ctx, **STEPS[step]) for step in args.steps
              if STEPS[step]["precision"] == "fp32" or ctx.has_f16}
    rng = np.random.default_rng(args.seed)
    header = (f"{'size':>10} {'engine':>12} {'ms/frame':>9} {'CPU s':>7} {'GFLOP/s':>8} {'conv GF/s':>9} "
              f"{'% FMA':>6} {'peak MiB':>9} {'CPU vs ORT':>10}")
    print(header)
    for size in args.sizes:
        height, width = SIZES[size]
        x = rng.uniform(0, 1, (1, 10, height, width)).astype(np.float32)
        reference, reference_cpu = time_onnxruntime(path, x, args.repeats)
        # On a shared machine the ceiling moves too: it is measured before the steps and after each one,
        # and the highest reading is the one every step is held against.
        ceilings = [fma_ceiling(ctx)]
        label = f"{height}x{width}"
        rows = []
        for step, model in models.items():
            try:
                seconds, cpu, conv_seconds, conv_flops = time_engine(model, x, args.repeats)
            except WgpuRtError as err:
                rows.append((f"{label:>10} {step:>12} skipped: {err}", None))
                continue
            ceilings.append(fma_ceiling(ctx))
            plan = model.plan(height, width)
            conv_rate = conv_flops / conv_seconds / 1e9
            rows.append((f"{label:>10} {step:>12} {seconds * 1e3:9.1f} {cpu:7.2f} {plan.flops / seconds / 1e9:8.1f} "
                         f"{conv_rate:9.1f} {{percent:5.0f}}% {plan.peak_bytes / 2**20:9.1f} "
                         f"{cpu / reference_cpu:9.2f}x", conv_rate))
        ceiling = max(ceilings)
        print(f"{label:>10} {'FMA ceiling':>12} {'':9} {'':7} {ceiling:8.1f}   (highest of {len(ceilings)} readings, "
              f"lowest {min(ceilings):.1f})")
        print(f"{label:>10} {'onnxruntime':>12} {reference * 1e3:9.1f} {reference_cpu:7.2f}")
        for row, conv_rate in rows:
            print(row if conv_rate is None else row.format(percent=100 * conv_rate / ceiling))
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
