"""``wgpu-rt blend``: a model between a network and its fine-tune (weight-space interpolation)."""

HELP = "write a model whose weights lie between a network and its fine-tune, with a card saying so"


def add_arguments(parser) -> None:
    parser.add_argument("base", help="the model the fine-tune started from (.onnx)")
    parser.add_argument("tuned", help="its fine-tune (.onnx, the same graph)")
    parser.add_argument("--weight", type=float, required=True,
                        help="how far towards the fine-tune: 0 is the base, 1 the fine-tune")
    parser.add_argument("-o", "--out", required=True, help="the .onnx to write; its card goes beside it (.md)")


def run(args) -> int:
    from ..train.blend import blend_models

    out = blend_models(args.base, args.tuned, args.weight, args.out)
    print(f"wrote {out} and {out.with_suffix('.md')}")
    return 0
