"""``wgpu-rt train``: train one network on a rendered dataset and export it to ONNX + model card."""

HELP = "train the denoiser, error predictor or confidence model on a dataset and export ONNX + model card"


def add_arguments(parser) -> None:
    parser.add_argument("task", choices=["denoiser", "error-predictor", "confidence"])
    parser.add_argument("--data", required=True, help="dataset folder from `wgpu-rt dataset`")
    parser.add_argument("--out", default="models", help="where the .onnx and .md go (default: %(default)s)")
    parser.add_argument("--epochs", type=int, default=20, help="default: %(default)s")
    parser.add_argument("--batch", type=int, default=4, help="default: %(default)s")
    parser.add_argument("--lr", type=float, default=1e-3, help="peak learning rate (default: %(default)s)")
    parser.add_argument("--crop", type=int, nargs=2, default=(128, 256), metavar=("MIN", "MAX"),
                        help="random crop size range in pixels (default: 128 256)")
    parser.add_argument("--widths", type=int, nargs="+", default=(32, 64, 128),
                        help="denoiser UNet level widths (default: 32 64 128)")
    parser.add_argument("--pixel-loss", choices=["l1", "charbonnier"], default="l1")
    parser.add_argument("--max-views", type=int, help="use at most this many views per split")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--checkpoints", help="checkpoint folder (default: OUT/checkpoints)")
    parser.add_argument("--resume", action="store_true", help="continue from the last checkpoint")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args) -> int:
    from ..train import TrainConfig, train

    config = TrainConfig(task=args.task, data=args.data, out=args.out, epochs=args.epochs, batch=args.batch,
                         lr=args.lr, seed=args.seed, crop_min=args.crop[0], crop_max=args.crop[1],
                         pixel_loss=args.pixel_loss, widths=tuple(args.widths), resume=args.resume,
                         max_views=args.max_views, checkpoints=args.checkpoints)
    summary = train(config, progress=not args.quiet)
    metrics = ", ".join(f"{k} {v:.4g}" for k, v in summary["metrics"].items() if isinstance(v, float))
    print(f"wrote {summary['onnx']} and {summary['card']} ({summary['seconds'] / 60:.1f} min); {metrics}")
    return 0
