"""``wgpu-rt dataset``: render training data (noisy renders, G-buffers, gold) with the truth engine."""

HELP = "render a training dataset: noisy renders at several spp, G-buffers and gold images (resumable)"
DEFAULT_SCENES = ("cornell", "cornell-glossy", "sun-room", "moving")


def _int_list(text: str) -> tuple[int, ...]:
    import argparse

    try:
        values = tuple(int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}") from None
    if not values or min(values) < 1:
        raise argparse.ArgumentTypeError(f"sample counts must be ≥ 1, got {text!r}")
    return values


def _shard(text: str) -> tuple[int, int]:
    import argparse

    try:
        index, count = (int(v) for v in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--shard expects i/n (e.g. 0/4), got {text!r}") from None
    if not 0 <= index < count:
        raise argparse.ArgumentTypeError(f"--shard i/n needs 0 ≤ i < n, got {text!r}")
    return index, count


def add_arguments(parser) -> None:
    parser.add_argument("--scenes", nargs="+",
                        help="built-in scene names or scene files, each rendered as --views randomized views "
                             f"(default: {' '.join(DEFAULT_SCENES)}; none when --worlds is given)")
    parser.add_argument("--views", type=int, default=16, help="views per scene (default: %(default)s)")
    parser.add_argument("--worlds", type=int, default=0, metavar="N",
                        help="also render N procedurally generated worlds (rooms, open ground, studio sets with "
                             "varied objects, materials and lights), one view each; with --meshes they draw "
                             "from that folder too (default: %(default)s)")
    parser.add_argument("--family", choices=("training", "held_out"), default="training",
                        help="the worlds' family: 'training' worlds become train/val views, 'held_out' worlds "
                             "(other seeds, other shapes and meshes, never trained on) become test views; "
                             "render the two into separate --out folders (default: %(default)s)")
    parser.add_argument("--size", type=int, default=256, help="square image size in pixels (default: %(default)s)")
    parser.add_argument("--spp", type=_int_list, default=(1, 4, 16),
                        help="noisy sample counts, comma-separated (default: 1,4,16)")
    parser.add_argument("--aux-samples", type=int, metavar="N",
                        help="re-estimate the noisy renders' albedo from N delta-chain paths per pixel, 2·N where "
                             "they meet glass or mirrors, 4 times those through a thin lens (0: the tracer's own; "
                             "default: as a denoising render does)")
    parser.add_argument("--noisy-copies", type=int, default=1, metavar="N",
                        help="independent renders per frame at the lowest --spp: N noise realizations of each view "
                             "for training, each costing 1/gold of the gold render; raise it on a finished "
                             "dataset to add copies (default: %(default)s)")
    parser.add_argument("--gold", type=int, default=4096, help="spp of the gold images (default: %(default)s)")
    parser.add_argument("--gold-renderer", choices=("ours", "mitsuba"), default="ours",
                        help="who renders the gold's colour: our tracer, or Mitsuba 3 (the bench extra) in its "
                             "fastest variant here, several times faster on a CPU; G-buffers stay ours "
                             "(default: %(default)s)")
    parser.add_argument("--max-depth", type=int, default=8, help="path depth (default: %(default)s)")
    parser.add_argument("--sequence-length", type=int, default=3,
                        help="frames in a temporal sequence (default: %(default)s)")
    parser.add_argument("--sequence-fraction", type=float, default=0.25,
                        help="fraction of views that are sequences (default: %(default)s)")
    parser.add_argument("--meshes", help="a folder of meshes (.obj/.ply/.stl/.glb…) to place in views, every file "
                        "read before anything is written; generated worlds split it by a hash of the file "
                        "name: a fifth of the files appear only in held-out worlds")
    parser.add_argument("--seed", type=int, default=0, help="dataset seed (default: %(default)s)")
    parser.add_argument("--shard", type=_shard, default=(0, 1), help="render only shard i of n (i/n)")
    parser.add_argument("-o", "--out", required=True, help="dataset folder (rerun to resume)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args) -> int:
    from pathlib import Path

    from ..dataset import DatasetConfig, DatasetError, TruthEngine
    from ..trace.trace_pass import AUX_SAMPLES

    if args.meshes and not Path(args.meshes).is_dir():
        raise DatasetError(f"{args.meshes}: --meshes must be a folder of mesh files")
    scenes = args.scenes if args.scenes is not None else (() if args.worlds else DEFAULT_SCENES)
    config = DatasetConfig(scenes=tuple(scenes), views=args.views, size=args.size, spp=args.spp,
                           gold=args.gold, seed=args.seed, max_depth=args.max_depth,
                           sequence_length=args.sequence_length, sequence_fraction=args.sequence_fraction,
                           noisy_copies=args.noisy_copies,
                           aux_samples=AUX_SAMPLES if args.aux_samples is None else args.aux_samples,
                           mesh_dir=str(Path(args.meshes).resolve()) if args.meshes else None,
                           worlds=args.worlds, family=args.family, gold_renderer=args.gold_renderer)
    rendered = TruthEngine(config, args.out).run(args.shard, progress=not args.quiet)
    print(f"rendered {len(rendered)} views into {args.out} "
          f"({sum(r.seconds for r in rendered):.1f} s); manifest: {Path(args.out) / 'manifest.json'}")
    return 0
