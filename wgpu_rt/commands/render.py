"""``wgpu-rt render``: path trace a scene to an EXR (color + AOV layers) or a tonemapped PNG preview."""

HELP = "path trace a scene (built-in name or scene file) to .exr (color + AOVs) or .png"


def add_arguments(parser) -> None:
    parser.add_argument("scene", help="built-in scene (cornell, cornell-glossy, sun-room, mesh, moving) "
                        "or a .json/.toml scene file")
    parser.add_argument("--spp", type=int, default=64, help="samples per pixel (default 64)")
    parser.add_argument("--size", default="256x256", help="WIDTHxHEIGHT (default 256x256)")
    parser.add_argument("--max-depth", type=int, default=8,
                        help="path segments, as Mitsuba's max_depth: 1 = emitters only (default 8)")
    parser.add_argument("--seed", type=int, default=0, help="sampling seed (same seed, same image)")
    parser.add_argument("--aov", default="albedo,normal,depth,motion",
                        help="comma-separated AOV layers for .exr output: albedo, normal, depth, motion, spp "
                        "('' for none)")
    parser.add_argument("--frames", help="A:B renders frames A..B-1 (the output needs a {frame} field)")
    parser.add_argument("--mesh", help="mesh file for the built-in 'mesh' scene")
    parser.add_argument("--out", default="render.exr",
                        help="output .exr or .png; may hold {frame}, e.g. out/{frame:04d}.exr")
    from ..frame.command import add_arguments as add_frame_arguments
    add_frame_arguments(parser)


def parse_frames(text: str | None) -> range:
    from ..errors import WgpuRtError

    if text is None:
        return range(0, 1)
    try:
        start, stop = (int(v) for v in text.split(":"))
    except ValueError:
        raise WgpuRtError(f"--frames {text!r}: expected A:B with integers A < B, e.g. 0:16") from None
    if not 0 <= start < stop:
        raise WgpuRtError(f"--frames {text!r}: need 0 <= A < B")
    return range(start, stop)


def output_paths(pattern: str, frames: range, many: bool) -> list:
    from pathlib import Path

    from ..errors import WgpuRtError

    suffix = Path(pattern).suffix.lower()
    if suffix not in (".exr", ".png"):
        raise WgpuRtError(f"--out {pattern!r}: the output must end in .exr or .png")
    if many and "{frame" not in pattern:
        raise WgpuRtError(f"--out {pattern!r}: several frames need a {{frame}} field, e.g. out/{{frame:04d}}.exr")
    try:
        paths = [Path(pattern.format(frame=f)) for f in frames]
    except (KeyError, IndexError, ValueError) as err:
        raise WgpuRtError(f"--out {pattern!r}: bad format field ({err}); only {{frame}} is known") from None
    for path in paths:   # missing folders are created when the image is written
        blocker = next((p for p in (path.parent, *path.parent.parents) if p.exists()), None)
        if blocker is not None and not blocker.is_dir():
            raise WgpuRtError(f"--out {path}: {blocker} is a file, not a folder")
    return paths


def run(args) -> int:
    from ..frame.command import run_fused, wants_fused
    if wants_fused(args):
        return run_fused(args)
    from ..errors import WgpuRtError
    from ..frame.tonemap import tonemap
    from ..io import write_exr, write_png
    from ..render import check_aovs, parse_size, render
    from ..scene import load_scene

    size = parse_size(args.size)
    if args.spp < 1:
        raise WgpuRtError(f"--spp {args.spp}: must be at least 1")
    if args.max_depth < 1:
        raise WgpuRtError(f"--max-depth {args.max_depth}: must be at least 1")
    aovs = check_aovs([a.strip() for a in args.aov.split(",") if a.strip()])
    frames = parse_frames(args.frames)
    paths = output_paths(args.out, frames, args.frames is not None and len(frames) > 1)
    scene = load_scene(args.scene, mesh=args.mesh)
    for frame, path in zip(frames, paths):
        result = render(scene, spp=args.spp, size=size, max_depth=args.max_depth, seed=args.seed,
                        frame=frame, aovs=aovs, progress=True)
        if path.suffix.lower() == ".exr":
            write_exr(path, result.color, result.aovs)
        else:
            write_png(path, tonemap(result.color, output="f32")[..., :3])
        print(f"{path}: {size[0]}x{size[1]}, {args.spp} spp, {result.seconds:.2f} s "
              f"({result.samples_per_second / 1e6:.2f} M samples/s)")
    return 0
