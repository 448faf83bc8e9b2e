"""``wgpu-rt profile``: per-dispatch GPU time of an ONNX network run by the WGSL engine (timestamp queries)."""

HELP = "time every dispatch of an ONNX network on the GPU (layer, kernel, shape, FLOP/s, workgroups)"

SHORT_DISPATCH_SECONDS = 50e-6  # dispatches this short are mostly launch overhead on a GPU


def add_arguments(parser) -> None:
    parser.add_argument("model", help="ONNX file, or a shipped network: denoiser, error-predictor, confidence")
    parser.add_argument("--size", default="1920x1088", help="input WIDTHxHEIGHT (default 1920x1088)")
    parser.add_argument("--precision", choices=("auto", "fp32", "fp16"), default="auto",
                        help="activation storage type (fp16 needs the shader-f16 feature; auto: fp16 on "
                             "discrete GPUs that have it, else fp32)")
    parser.add_argument("--conv-tiling", help="convolution kernels: none, loop, register, staged, staged-weights "
                        "or staged-narrow (default: the adapter's, as inference picks them; see wgpu_rt.nn.WgslModel)")
    parser.add_argument("--weight-fetch", choices=("subgroup", "direct"),
                        help="how convolutions read weights: the lanes of a subgroup sharing the loads, or each "
                        "invocation loading its own (default: subgroup where the adapter has subgroups)")
    parser.add_argument("--math", choices=("f32", "f16", "f16-acc"),
                        help="what the 3×3 convolutions multiply in: f32, or with fp16 activations f16 (each "
                        "kernel row's products summed in half precision) or f16-acc (the sums over input "
                        "channels too); default: as inference picks it (f16-acc, else f16, on discrete GPUs in fp16 whose "
                        "f16 kernels pass a check against f32 math)")
    parser.add_argument("--repeat", type=int, default=5,
                        help="timed runs after one warm-up; times are their median (default 5)")
    parser.add_argument("--sort", choices=("order", "time"), default="order",
                        help="row order: as recorded (default) or slowest first")
    parser.add_argument("--json", metavar="OUT", help="also write the rows and totals to this JSON file")


def model_path(text: str):
    """``text`` as a path, unless no such file exists and it names a shipped network."""
    from pathlib import Path

    from ..models import network_named

    path = Path(text)
    if not path.exists():
        try:
            return network_named(text).path()
        except KeyError:
            pass
    return path


def rate_unit(profile) -> tuple[str, float]:
    """TFLOP/s once any dispatch reaches 1 TFLOP/s, else GFLOP/s."""
    fastest = max((row.flops_per_second or 0.0 for row in profile.rows), default=0.0)
    return ("TFLOP/s", 1e12) if fastest >= 1e12 else ("GFLOP/s", 1e9)


def table(profile, sort: str) -> list[str]:
    unit, scale = rate_unit(profile)
    rows = sorted(profile.rows, key=lambda r: -r.seconds) if sort == "time" else profile.rows
    total = profile.dispatch_seconds
    width = max(len(row.label) for row in rows) + (4 if profile.bands > 1 else 0)
    kernel_width = max(len(row.kernel) for row in rows)
    header = (f"{'#':>4}  {'layer':<{width}}  {'kernel':<{kernel_width}} {'output C×H×W':>14} {'workgroups':>18} "
              f"{'GFLOP':>8} {'ms':>9} {unit:>8} {'share':>6}")
    lines = [header]
    for row in rows:
        label = f"b{row.band} {row.label}" if profile.bands > 1 else row.label
        rate = row.flops_per_second
        groups = "×".join(map(str, row.workgroups))
        lines.append(
            f"{row.index:>4}  {label:<{width}}  {row.kernel:<{kernel_width}} {'×'.join(map(str, row.output)):>14} "
            f"{row.workgroup_count:>7} {groups:>10} {row.flops / 1e9:8.3f} {row.seconds * 1e3:9.3f} "
            f"{'-' if rate is None else f'{rate / scale:.2f}':>8} {100 * row.seconds / total if total else 0:5.1f}%")
    return lines


def summary(profile) -> list[str]:
    rows, bands = profile.rows, profile.bands
    width, height = profile.size
    canvas = f"{profile.canvas[0]}x{profile.canvas[1]}"
    if bands > 1:
        canvas = f", in {bands} bands of {canvas}"
    else:
        canvas = "" if profile.canvas == profile.size else f", canvas {canvas}"
    short = [row for row in rows if row.seconds < SHORT_DISPATCH_SECONDS]
    dispatched = sum(row.flops for row in rows)
    runs = f"{profile.repeat} timed run{'s' if profile.repeat > 1 else ''}"
    per_band = f" ({len(rows) // bands} per band)" if bands > 1 else ""
    short_ms = sum(row.seconds for row in short) * 1e3
    lines = [
        (f"{profile.model} at {width}x{height}{canvas}, {profile.precision}, {profile.conv_tiling} conv tiling, "
         f"{profile.weight_fetch} weight fetch, {profile.math} math, on {profile.adapter}; median of {runs}"),
        (f"dispatches: {len(rows)}{per_band}; {len(short)} under {SHORT_DISPATCH_SECONDS * 1e6:.0f} µs "
         f"({short_ms:.3f} ms in all)"),
        (f"GPU time: {profile.dispatch_seconds * 1e3:.3f} ms summed over dispatches (each in its own timed "
         f"pass), {profile.end_to_end_seconds * 1e3:.3f} ms end to end (one pass, as an inference runs)"),
    ]
    work = f"work: {profile.network_flops / 1e9:.3f} GFLOP"
    if dispatched != profile.network_flops:
        work += f" (+{(dispatched - profile.network_flops) / 1e9:.3f} GFLOP recomputed in the bands' context rows)"
    if profile.end_to_end_seconds > 0:
        work += f", {profile.network_flops / profile.end_to_end_seconds / 1e9:.1f} GFLOP/s end to end"
    return lines + [work]


def run(args) -> int:
    import json

    from ..errors import WgpuRtError
    from ..io import atomic_output, check_output_path
    from ..nn import WgslModel
    from ..nn.profile import profile
    from ..renderer import parse_size

    width, height = parse_size(args.size)
    if args.repeat < 1:
        raise WgpuRtError(f"--repeat {args.repeat}: must be at least 1")
    output = check_output_path(args.json, "--json", (".json",)) if args.json else None
    model = WgslModel(model_path(args.model), precision=args.precision, conv_tiling=args.conv_tiling,
                      weight_fetch=args.weight_fetch, math=args.math)
    result = profile(model, height, width, repeat=args.repeat)
    print("\n".join(table(result, args.sort) + [""] + summary(result)))
    if output is not None:
        with atomic_output(output) as tmp:
            tmp.write_text(json.dumps(result.as_dict(), indent=1) + "\n")
        print(f"rows -> {output}")
    return 0
