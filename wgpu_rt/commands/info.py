"""``wgpu-rt info``: which adapter would be used and what it can do."""

HELP = "print the adapters, the one chosen, its backend, features, limits and the choices measured on it"


def add_arguments(parser) -> None:
    parser.add_argument("--all", action="store_true", help="also print every limit")


def run(args) -> int:
    from ..gpu import OPTIONAL_FEATURES, adapter_label, get_context, list_adapters

    for adapter in list_adapters():
        print(f"available: {adapter_label(adapter)}")
    ctx = get_context()
    info = ctx.adapter.info
    print(f"chosen:    {ctx.label}")
    print(f"backend:   {info.get('backend_type')}   type: {info.get('adapter_type')}   "
          f"driver: {info.get('description')}")
    for feature in OPTIONAL_FEATURES:
        print(f"feature:   {feature:16s} {'yes' if feature in ctx.features else 'no'}")
    shown = ctx.limits if args.all else {k: v for k, v in ctx.limits.items() if "storage" in k
                                          or "compute" in k or k == "max-buffer-size"}
    for name, value in sorted(shown.items()):
        print(f"limit:     {name:44s} {value}")
    print_engine_defaults(ctx)
    print_measured_choices(ctx)
    return 0


def print_engine_defaults(ctx) -> None:
    """How the NN engine runs convolutions here unless told otherwise (wgpu_rt.nn.model)."""
    from ..nn import autotune
    from ..nn.model import (default_conv_tiling, default_math, default_precision, default_uniform_windows,
                            default_weight_fetch)

    tuned = "on" if autotune.enabled(None) else "off ($WGPU_RT_AUTOTUNE=1 measures per layer)"
    precision = default_precision(ctx)
    print(f"nn engine: precision {precision} ({default_math(ctx, precision)} math), "
          f"conv tiling {default_conv_tiling(ctx)}, weight fetch {default_weight_fetch(ctx)}, "
          f"{'per-group uniform windows' if default_uniform_windows(ctx) else 'one dispatch per layer'}, "
          f"autotuning {tuned}")


def print_measured_choices(ctx) -> None:
    """What this adapter measured and kept (wgpu_rt.measured_choices): BVH variants per scene size,
    convolution kernels per layer shape where autotuning ran, each with its candidates' times."""
    from ..measured_choices import MeasuredChoices

    choices = MeasuredChoices(ctx)
    prefix = choices.adapter + " | "
    mine = sorted((key[len(prefix):], entry) for key, entry in choices.entries.items() if key.startswith(prefix))
    print(f"measured:  {len(mine)} choice(s) kept for this adapter in {choices.path}")
    for what, entry in mine:
        seconds = entry.get("seconds") if isinstance(entry.get("seconds"), dict) else {}
        times = ", ".join(f"{variant} {float(value) * 1e3:.3g} ms" for variant, value in seconds.items())
        failed = entry.get("failed") if isinstance(entry.get("failed"), dict) else {}
        times += "".join(f", {variant} failed" for variant in failed)
        print(f"measured:  {what}: {entry['variant']}" + (f" ({times})" if times else ""))
