"""``wgpu-rt train``: train one network on a rendered dataset and export it to ONNX + model card."""

from ..models import NETWORKS

HELP = "train the denoiser, error predictor or confidence model on a dataset and export ONNX + model card"

FRESH_LR = 1e-3       # a run from fresh weights (TrainConfig's default)
FINE_TUNE_LR = 1e-4   # a run --init-from a model: the shipped fine-tunes took 7e-5 to 2e-4 (BENCHMARKS.md §31–§45)


def _curriculum_stage(text: str) -> int | str:
    """A --curriculum stage: a sample count (TrainConfig checks it), or 'any'."""
    import argparse

    from ..train.samples import ANY_SPP

    if text == ANY_SPP:
        return ANY_SPP
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a sample count or '{ANY_SPP}', got {text!r}") from None


def add_arguments(parser) -> None:
    parser.add_argument("task", choices=[network.cli_name for network in NETWORKS.values()])
    parser.add_argument("--data", required=True, help="dataset folder from `wgpu-rt dataset`")
    parser.add_argument("--extra-data", nargs="+", default=(), metavar="DIR",
                        help="more dataset folders whose train/val splits join training/validation")
    parser.add_argument("-o", "--out", default="models", help="where the .onnx and .md go (default: %(default)s)")
    parser.add_argument("--epochs", type=int, default=20, help="default: %(default)s")
    parser.add_argument("--batch", type=int, default=4, help="default: %(default)s")
    parser.add_argument("--lr", type=float,
                        help=f"peak learning rate (default: {FRESH_LR}; {FINE_TUNE_LR} with --init-from)")
    parser.add_argument("--crop", type=int, nargs=2, default=(128, 256), metavar=("MIN", "MAX"),
                        help="random crop size range in pixels (default: 128 256)")
    parser.add_argument("--widths", type=int, nargs="+",
                        help="denoiser UNet level widths (default: 32 64 128, or with --init-from the model's own); "
                             "the engine's fast 3×3 kernels take multiples of 8 channels, other widths run on its "
                             "loop kernel, several times slower on a GPU")
    parser.add_argument("--bottom-merge", choices=["concat", "add"],
                        help="denoiser: the deepest level's upsampled output is concatenated with the skip above "
                             "it and merged by two 3×3 convs, or added to it (cheaper; default: concat, or with "
                             "--init-from the model's own)")
    parser.add_argument("--residual", action="store_true",
                        help="denoiser predicts a correction to its noisy input's log1p colour")
    parser.add_argument("--curriculum", type=_curriculum_stage, nargs="+", default=(16, 4, 1), metavar="SPP",
                        help="denoiser input spp per equal share of the epochs; 'any': each crop draws one of "
                             "its view's rendered sample counts (default: 16 4 1)")
    parser.add_argument("--pixel-loss", choices=["l1", "charbonnier"], default="l1")
    parser.add_argument("--ssim-space", choices=["log", "display"], default="log",
                        help="denoiser SSIM term on log1p colour or on the metrics' display values")
    parser.add_argument("--lowpass", type=float, default=0.0, metavar="WEIGHT",
                        help="denoiser: add WEIGHT × L1 of 8×8 block means of the compared colours, against "
                             "low-frequency blotches (default: 0, off)")
    parser.add_argument("--log-mse", type=float, default=0.0, metavar="WEIGHT",
                        help="denoiser: add WEIGHT × the mean over crops of log10(1 + display MSE / 1e-6), so "
                             "each crop's relative error counts alike, as a mean PSNR does (default: 0, off)")
    parser.add_argument("--edge", type=float, default=0.0, metavar="WEIGHT",
                        help="denoiser: add WEIGHT × L1 of display colours within 2 px of a silhouette or crease "
                             "in the albedo, normal or depth planes, where a thin line's error is diluted in the "
                             "other terms' means (default: 0, off)")
    parser.add_argument("--permute-colours", action="store_true",
                        help="denoiser: draw a random order of the R, G, B channels per crop (colour, albedo and "
                             "target alike), so bounce light of every hue is seen (default: off)")
    parser.add_argument("--auto-exposure", choices=["on", "off"], default="on",
                        help="bring each input to one key before the network (denoiser: the frame's "
                             "irradiance; error predictor: its probe's radiance; confidence: the denoised "
                             "frame's), as the runtime then does when it runs the model (the ONNX file records "
                             "it; default: on)")
    parser.add_argument("--max-views", type=int, help="use at most this many views per split")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--checkpoints", help="checkpoint folder (default: OUT/checkpoints)")
    parser.add_argument("--resume", action="store_true", help="continue from the last checkpoint")
    parser.add_argument("--init-from", metavar="CHECKPOINT",
                        help="fine-tune: start from another run's checkpoint (.pt) or an exported model (.onnx, "
                             "e.g. the shipped one) of the same task and widths (or, for the denoiser, --widths with "
                             "one level more: it starts as the shallower model; narrower at every level: each "
                             "layer keeps its heaviest channels; or wider at some levels: the new channels start "
                             "unread), with a fresh optimizer and "
                             "schedule; give this run its own --checkpoints folder")
    parser.add_argument("--validate-every", type=int, default=1, metavar="N",
                        help="validate every N epochs and after the last (validation is slow on a CPU)")
    parser.add_argument("--device", choices=["auto", "cuda", "cpu"], default="auto",
                        help="train with CUDA torch (data kept on the GPU, mixed precision) or on the CPU; auto: "
                             "CUDA when torch sees it. Under `torchrun --nproc_per_node=N -m wgpu_rt train ...` "
                             "N processes train one model data-parallel (default: %(default)s)")
    parser.add_argument("--minutes", type=float,
                        help="time budget: after every epoch, --epochs is set to what fits at the pace of the "
                             "epochs after the first (never more than asked; the learning-rate schedule then "
                             "decays inside the budget; the card says so)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args) -> int:
    from ..train import TrainConfig, train
    from ..train.context import end_data_parallel_process
    from ..train.trainer import base_architecture

    # a fine-tune keeps the model's architecture and takes smaller steps, unless told otherwise
    base = base_architecture(args.init_from) if args.init_from and args.task == "denoiser" else {}
    widths = args.widths or base.get("widths", (32, 64, 128))
    bottom_merge = args.bottom_merge or base.get("bottom_merge", "concat")
    lr = args.lr if args.lr is not None else FINE_TUNE_LR if args.init_from else FRESH_LR
    config = TrainConfig(task=args.task, data=args.data, out=args.out, epochs=args.epochs, batch=args.batch,
                         lr=lr, seed=args.seed, crop_min=args.crop[0], crop_max=args.crop[1],
                         pixel_loss=args.pixel_loss, ssim_space=args.ssim_space, lowpass=args.lowpass,
                         log_mse=args.log_mse, edge=args.edge,
                         permute_colours=args.permute_colours, auto_exposure=args.auto_exposure == "on",
                         widths=tuple(widths), residual=args.residual, bottom_merge=bottom_merge,
                         curriculum=tuple(args.curriculum), resume=args.resume,
                         extra_data=tuple(args.extra_data), max_views=args.max_views,
                         checkpoints=args.checkpoints, init_from=args.init_from,
                         validate_every=args.validate_every, device=args.device,
                         minutes=args.minutes)
    summary = train(config, progress=not args.quiet)
    if summary is not None:   # None: a data-parallel rank other than 0; rank 0 reports
        metrics = ", ".join(f"{k} {v:.4g}" for k, v in summary["metrics"].items() if isinstance(v, float))
        print(f"wrote {summary['onnx']} and {summary['card']} ({summary['seconds'] / 60:.1f} min); {metrics}")
    end_data_parallel_process(0)
    return 0
