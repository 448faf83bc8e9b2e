"""``wgpu-rt info``: which adapter would be used and what it can do."""

HELP = "print the adapters, the one chosen, its backend, features and limits"


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
    return 0
