"""U-Net inference: the WGSL engine (naive → tiled → fp16 steps) against onnxruntime, torch and OIDN, same run.

For each size it prints ms per frame (wall clock, best run) and CPU seconds per frame (this process's
threads, lavapipe's workers included: on a shared machine this is the stable number, and the ratio
column compares it), GFLOP/s of the whole network (per wall second) and of the conv kernels alone
(timestamp queries around every dispatch, best of the repeats), that rate as a percent of the adapter's
FMA ceiling (measured here with benchmarks/fma_peak.wgsl before the steps and after each, the highest
reading counting; where the adapter has shader-f16 the f16 ceiling is printed beside it), the planned peak activation memory, the ratio to onnxruntime's
time (intra-op threads = CPU cores), and the largest difference from onnxruntime's output over
max(1, max |output|) (the parity tests' bound: 1e-4 in fp32, 1e-2 with fp16 activations), so a step that
is fast because it is wrong shows it. Steps: ``naive`` = one output pixel per invocation,
``loop-tiled`` = 4-pixel tiles in loops, ``reg-tiled`` = plus conv3x3.wgsl's written-out 4-pixel ×
32-channel tile (16 where the output is not 32k channels; the default on CPU and integrated adapters),
``staged`` = the 16-channel tile with its input staged in workgroup memory (conv3x3_staged.wgsl, the
default on discrete GPUs), ``staged-weights`` = that kernel with each input block's weight blocks staged
in workgroup memory too (loaded once per workgroup and read by every invocation from there, as tfjs and
onnxruntime's WebGPU convolutions do), ``fp16`` = the adapter's default tiling with f16 activations, ``fp16-math`` = that with the 3×3
convolutions' multiply-adds in half precision too (each kernel row's products summed in f16),
``fp16-acc`` = that with the sums over input channels in f16 as well (an f16 register tile),
``direct-weights`` = the default tiling with every invocation loading its own weight blocks (instead of
the lanes of a subgroup sharing the loads and broadcasting them, the default where the adapter has
subgroups), ``autotuned`` = the tiling and weight fetch of every layer measured on this adapter
(wgpu_rt.nn.autotune: the first run on an adapter times the candidates, before the timed frames, and
caches the choice in the user's cache folder). Every step runs
the same 2×2 transposed-convolution kernel (conv_transpose.wgsl, 4 input pixels per invocation) and its
dispatches count as conv dispatches.

Peers at the same sizes, in the same run (benchmarks/peers.py finds them; an absent one prints one
"skipped (why)" line): torch running the same ONNX file (the layers our engine lowers it to) on the CPU
and, with a CUDA GPU, through cuDNN in fp32 and fp16; Intel OIDN (colour + albedo + normal, HDR) at
each ``--oidn-quality`` on the CPU and on CUDA. OIDN is a different network (its size set by the
quality, its own pre- and post-processing): its rows say what a production denoiser costs at that
size, not the same FLOPs.
Peer times are best of the repeats after warm-up, with inputs already on the peer's device (CUDA ones
between CUDA events); "ours ÷ peer" divides the fastest engine step's wall time by the peer's, and
"CPU s ÷ peer" its CPU seconds by a CPU peer's when our adapter is a CPU one (lavapipe).

    python3 benchmarks/bench_nn.py --sizes 256 512            # add 1080p for the full-HD run (slow)
    python3 benchmarks/bench_nn.py --model models/denoiser.onnx   # the shipped denoiser instead
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import peers

SIZES = {"256": (256, 256), "512": (512, 512), "1080p": (1080, 1920)}
STEPS = {"naive": {"precision": "fp32", "conv_tiling": "none"},
         "loop-tiled": {"precision": "fp32", "conv_tiling": "loop"},
         "reg-tiled": {"precision": "fp32", "conv_tiling": "register"},
         "staged": {"precision": "fp32", "conv_tiling": "staged"},
         "staged-weights": {"precision": "fp32", "conv_tiling": "staged-weights"},
         "fp16": {"precision": "fp16", "conv_tiling": None},
         "fp16-math": {"precision": "fp16", "conv_tiling": None, "math": "f16"},
         "fp16-acc": {"precision": "fp16", "conv_tiling": None, "math": "f16-acc"},
         "direct-weights": {"precision": "fp32", "conv_tiling": None, "weight_fetch": "direct"},
         "autotuned": {"precision": "fp32", "conv_tiling": None, "autotune": True}}


def fma_ceiling(ctx, half: bool = False) -> float:
    """GFLOP/s of the FMA loop kernel (best of 4), in f32 or with ``half`` in f16. 32,768 invocations of
    4096 steps on a CPU adapter; elsewhere 16× the invocations (32,768 read 10–13 TFLOP/s on an H200, a
    fraction of what it does: BENCHMARKS.md §12) and 4× the steps, so that the submit and the readback's
    wait weigh less in the wall time (the H200's 29 TFLOP/s reading of §21 was 2.4 ms a dispatch)."""
    from wgpu_rt import shaders

    cpu = ctx.adapter.info.get("adapter_type") == "CPU"
    invocations, iterations = 64 * 512 * (1 if cpu else 16), 4096 * (1 if cpu else 4)
    pipeline = ctx.compute_pipeline(shaders.compose("fma_peak.wgsl", Path(__file__).parent, {
        "ITERATIONS": iterations, "SCALAR": "f16" if half else "f32", "ENABLE": "enable f16;" if half else ""}))
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


def time_onnxruntime(path: Path, x: np.ndarray, repeats: int) -> tuple[float, float, np.ndarray]:
    import onnxruntime as ort

    options = ort.SessionOptions()
    options.intra_op_num_threads = os.cpu_count()
    session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    output = session.run(None, {"input": x})[0]
    return (*peers.best_seconds(lambda: session.run(None, {"input": x}), repeats), output)


def time_engine(model, x: np.ndarray, repeats: int) -> tuple[float, float, float, int, np.ndarray]:
    """(best wall and CPU seconds per frame, seconds spent in conv-family dispatches, their FLOPs, the
    output)."""
    import wgpu

    ctx = model.ctx
    _, _, height, width = x.shape
    input_buffer = ctx.upload(x, label="bench input")
    output = model(x)  # builds the plan and compiles the pipelines

    def frame():
        encoder = ctx.device.create_command_encoder()
        output = model.record(encoder, input_buffer, height, width)
        ctx.device.queue.submit([encoder.finish()])
        ctx.read(output, nbytes=16)

    wall, cpu = peers.best_seconds(frame, repeats)
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
    return wall, cpu, conv_seconds, sum(dispatches[i].flops for i in conv), output


def print_peer_rows(label: str, x: np.ndarray, networks: list, oidn_devices: list[str], qualities: list[str],
                    repeats: int, flops: int, ours: tuple[str, float, float], cpu_adapter: bool) -> None:
    """The peers' rows at one size: torch on each of ``networks`` and OIDN on each device at each quality,
    each against ``ours`` (the fastest engine step: name, wall seconds, CPU seconds). A peer that fails
    here (out of memory, a driver error) prints one "skipped (why)" row."""
    _, _, height, width = x.shape
    step, our_seconds, our_cpu = ours
    timers = [(network.label, flops, lambda network=network: peers.time_torch(network, x, repeats))
              for network in networks]
    timers += [(f"OIDN {peers.DEVICE_NAMES[device]} {quality}", None,
                lambda device=device, quality=quality: peers.time_oidn(device, quality, height, width, repeats))
               for device in oidn_devices for quality in qualities]
    print(f"{label:>10} {f'peer (ours = {step})':>31} {'ms/frame':>9} {'CPU s':>7} {'GFLOP/s':>8} "
          f"{'ours ÷ peer':>11} {'CPU s ÷ peer':>12}")
    for name, peer_flops, measure in timers:
        try:
            seconds, cpu = measure()
        except RuntimeError as err:   # torch's out-of-memory errors and OIDN's failures are RuntimeErrors
            print(f"{label:>10} {peers.skipped(name, str(err).splitlines()[0])}")
            continue
        rate = f"{peer_flops / seconds / 1e9:8.1f}" if peer_flops else f"{'':8}"
        cpu_text = f"{cpu:7.2f}" if cpu is not None else f"{'':7}"
        cpu_ratio = f"{our_cpu / cpu:11.2f}x" if cpu_adapter and cpu is not None else ""
        print(f"{label:>10} {name:>31} {seconds * 1e3:9.1f} {cpu_text} {rate} {our_seconds / seconds:10.2f}x "
              f"{cpu_ratio}".rstrip())
        sys.stdout.flush()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", nargs="+", default=["256", "512"], choices=list(SIZES))
    parser.add_argument("--steps", nargs="+", default=list(STEPS), choices=list(STEPS))
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--model", type=Path, metavar="ONNX",
                        help="the network to run (default: an untrained UNet() with the training defaults' "
                             "widths, the one BENCHMARKS.md reports)")
    parser.add_argument("--oidn-quality", nargs="+", default=list(peers.QUALITIES), choices=peers.QUALITIES,
                        help="OIDN peer rows, one per quality and device")
    args = parser.parse_args(argv)

    import torch

    from wgpu_rt.errors import WgpuRtError
    from wgpu_rt.gpu import get_context
    from wgpu_rt.nn import WgslModel
    from wgpu_rt.nn.graph import load_graph
    from wgpu_rt.train.networks import UNet, export_onnx

    ctx = get_context()
    torch.manual_seed(args.seed)
    path = args.model or export_onnx(UNet(), Path(tempfile.mkdtemp()) / "unet.onnx")
    try:
        graph = load_graph(path)
    except WgpuRtError as err:   # a missing or unsupported --model
        parser.error(str(err))
    channels, multiple = graph.input_channels, graph.multiple
    print(f"adapter: {ctx.label}   CPU cores: {os.cpu_count()}   network: {args.model or 'UNet() (untrained)'}")
    torch_devices, skipped = peers.torch_devices()
    oidn_devices, oidn_skipped = peers.oidn_devices()
    for line in skipped + oidn_skipped:
        print(line)
    networks = [peers.TorchNetwork(path, device, precision) for device in torch_devices
                for precision in peers.torch_precisions(device)]
    cpu_adapter = ctx.adapter.info.get("adapter_type") == "CPU"
    models = {step: WgslModel(path, ctx=ctx, **STEPS[step]) for step in args.steps
              if STEPS[step]["precision"] == "fp32" or ctx.has_f16}
    rng = np.random.default_rng(args.seed)
    header = (f"{'size':>10} {'engine':>14} {'ms/frame':>9} {'CPU s':>7} {'GFLOP/s':>8} {'conv GF/s':>9} "
              f"{'% FMA':>6} {'peak MiB':>9} {'CPU vs ORT':>10} {'|Δ| vs ORT':>10}")
    print(header)
    for size in args.sizes:
        # the canvas every runner sees: padded to the network's size multiple, as the engine pads 1080 to
        # 1088 for a five-level U-Net (onnxruntime and torch refuse sizes the skips cannot match)
        height, width = (-(-side // multiple) * multiple for side in SIZES[size])
        x = rng.uniform(0, 1, (1, channels, height, width)).astype(np.float32)
        reference, reference_cpu, reference_output = time_onnxruntime(path, x, args.repeats)
        scale = max(1.0, float(np.abs(reference_output).max()))
        # On a shared machine the ceiling moves too: it is measured before the steps and after each one,
        # and the highest reading is the one every step is held against.
        ceilings = [fma_ceiling(ctx)]
        label = f"{height}x{width}"
        rows, measured, flops = [], [], None
        for step, model in models.items():
            try:
                seconds, cpu, conv_seconds, conv_flops, output = time_engine(model, x, args.repeats)
            except WgpuRtError as err:
                rows.append((f"{label:>10} {step:>14} skipped: {err}", None))
                continue
            ceilings.append(fma_ceiling(ctx))
            plan = model.plan(height, width)
            flops = plan.flops
            measured.append((step, seconds, cpu))
            conv_rate = conv_flops / conv_seconds / 1e9
            rows.append((f"{label:>10} {step:>14} {seconds * 1e3:9.1f} {cpu:7.2f} {plan.flops / seconds / 1e9:8.1f} "
                         f"{conv_rate:9.1f} {{percent:5.0f}}% {plan.peak_bytes / 2**20:9.1f} "
                         f"{cpu / reference_cpu:9.2f}x {np.abs(output - reference_output).max() / scale:10.1e}",
                         conv_rate))
        ceiling = max(ceilings)
        print(f"{label:>10} {'FMA ceiling':>14} {'':9} {'':7} {ceiling:8.1f}   (highest of {len(ceilings)} readings, "
              f"lowest {min(ceilings):.1f})")
        if ctx.has_f16:   # what the f16 multiply-adds (fp16-math) could reach; % FMA stays against f32
            half = max(fma_ceiling(ctx, half=True) for _ in range(2))
            print(f"{label:>10} {'FMA ceiling f16':>15} {'':8} {'':7} {half:8.1f}   (highest of 2 readings)")
        print(f"{label:>10} {'onnxruntime':>14} {reference * 1e3:9.1f} {reference_cpu:7.2f}")
        for row, conv_rate in rows:
            print(row if conv_rate is None else row.format(percent=100 * conv_rate / ceiling))
        sys.stdout.flush()
        if measured:
            ours = min(measured, key=lambda step: step[1])
            print_peer_rows(label, x, networks, oidn_devices, args.oidn_quality, args.repeats, flops, ours,
                            cpu_adapter)
        else:
            print(f"{label:>10} peers: skipped (no engine step ran at this size to compare with)")
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
