"""``wgpu-rt render``: a shell over ``wgpu_rt.render``. Path trace a scene, optionally denoise, sample
adaptively and accumulate over time on the device, and write an EXR (linear HDR colour + AOV layers) or
a PNG (the tone-mapped display image) per frame. Every flag means the same with or without ``--denoise``."""

from ._denoiser_flags import add_denoiser_flags, check_denoiser_flags, denoiser_options
from ._display_flags import add_display_flags, display_settings

HELP = "path trace a scene (built-in name, scene file or mesh file) to .exr (color + AOVs) or .png"

SUFFIXES = (".exr", ".png")
FRAMES_WITHOUT_CONFIRMATION = 100_000   # more output files than this need --max-files


def add_arguments(parser) -> None:
    parser.add_argument("scene", help="built-in scene (cornell, cornell-glossy, sun-room, painted, textured, mesh, "
                        "moving), a .json/.toml scene file, or a mesh file (.obj/.ply/.glb…: the 'mesh' scene "
                        "around it, in its own materials; a glTF file with a camera: its own scene, camera and "
                        "lights)")
    parser.add_argument("--spp", type=int, default=None,
                        help="samples per pixel per frame (default 64; 1 with --denoise; not with --adaptive)")
    parser.add_argument("--size", default="256x256", help="WIDTHxHEIGHT (default 256x256)")
    parser.add_argument("--max-depth", type=int, default=8,
                        help="path segments, as Mitsuba's max_depth: 1 = emitters only (default 8)")
    parser.add_argument("--seed", type=int, default=0, help="sampling seed (same seed, same image; frame f uses seed+f)")
    parser.add_argument("--aov", default="albedo,normal,depth,motion,spp",
                        help="comma-separated AOV layers for .exr output: albedo, normal, depth, motion, spp, "
                        "half_radiance and half_spp (the mean after half the samples, for `wgpu-rt denoise`), "
                        "radiance (the samples' mean before --denoise) ('' for none)")
    parser.add_argument("--frames", help="N renders frame N; A:B renders frames A..B-1 (the output needs a {frame} "
                        "field)")
    parser.add_argument("--mesh", help="mesh file for the built-in 'mesh' scene")
    parser.add_argument("--camera", help="which of a glTF scene's cameras to see it through: an index into the "
                        "file's cameras, or a camera's or its node's name (default: the first placed)")
    parser.add_argument("--animation", help="which of a glTF file's animations plays: an index into the file's "
                        "animations or an animation's name (default: all of them where no two move the same "
                        "node, else the first)")
    parser.add_argument("-o", "--out", default="render.exr",
                        help="output .exr or .png; may hold {frame}, e.g. out/{frame:04d}.exr")
    add_display_flags(parser)
    parser.add_argument("--denoise", action="store_true",
                        help="denoise on the device with models/denoiser.onnx")
    parser.add_argument("--adaptive", type=float, metavar="BUDGET",
                        help="adaptive sampling guided by models/error_predictor.onnx at BUDGET mean spp")
    parser.add_argument("--temporal", action="store_true",
                        help="temporal accumulation over --frames (reprojection, clamping, confidence)")
    parser.add_argument("--models", metavar="DIR",
                        help="folder of the networks to run instead of the shipped ones (denoiser.onnx, "
                             "error_predictor.onnx, confidence.onnx, as `wgpu-rt train --out DIR` writes them)")
    parser.add_argument("--aux-samples", type=int, metavar="N",
                        help="re-estimate the albedo layer from N delta-chain paths per pixel, 2·N where they "
                             "meet glass or mirrors, so it is noise-free there, 4 times those through a thin lens "
                             "(default: 4 with --denoise, else 0: the tracer's own)")
    add_denoiser_flags(parser, "frame")


def parse_frames(text: str | None) -> range:
    from ..errors import WgpuRtError

    if text is None:
        return range(0, 1)
    try:
        start, stop = (int(v) for v in text.split(":")) if ":" in text else (int(text), int(text) + 1)
    except ValueError:
        raise WgpuRtError(f"--frames {text!r}: expected a frame number N or A:B with integers A < B, e.g. 0:16") \
            from None
    if not 0 <= start < stop:
        raise WgpuRtError(f"--frames {text!r}: " + ("need 0 <= A < B" if ":" in text else "frames are numbered from 0"))
    return range(start, stop)


def check_pattern(pattern: str, frames: range) -> None:
    """The --out pattern formats every frame number (tried on the first and last only: the same fields
    format every integer alike) and names a .exr or .png file in a writable place."""
    from pathlib import Path

    from ..errors import WgpuRtError
    from ..io import check_output_path

    if len(frames) > 1 and "{frame" not in pattern:
        raise WgpuRtError(f"--out {pattern!r}: several frames need a {{frame}} field, e.g. out/{{frame:04d}}.exr")
    for frame in (frames[0], frames[-1]):
        check_output_path(output_path(pattern, frame), "--out", SUFFIXES)
    if len(frames) > 1 and output_path(pattern, frames[0]) == output_path(pattern, frames[-1]):
        raise WgpuRtError(f"--out {pattern!r}: every frame would write {Path(output_path(pattern, frames[0]))}")


def output_path(pattern: str, frame: int):
    from pathlib import Path

    from ..errors import WgpuRtError

    try:
        return Path(pattern.format(frame=frame))
    except (KeyError, IndexError, ValueError, AttributeError, TypeError) as err:
        raise WgpuRtError(f"--out {pattern!r}: bad format field ({type(err).__name__}: {err}); "
                          "only {frame} (an integer, e.g. {frame:04d}) is known") from None


def run(args) -> int:
    from ..errors import WgpuRtError
    from ..io import AUX_SAMPLES_ATTRIBUTE, write_exr, write_png
    from ..renderer import Renderer, check_aovs, check_int, parse_size

    size = parse_size(args.size)
    for flag, value, low, high in (("--spp", args.spp, 1, None), ("--max-depth", args.max_depth, 1, None),
                                   ("--seed", args.seed, 0, 2 ** 32 - 1), ("--aux-samples", args.aux_samples, 0, None)):
        if value is not None:
            check_int(flag, value, low, high)
    aovs = check_aovs(args.aov)
    frames = parse_frames(args.frames)
    if len(frames) > FRAMES_WITHOUT_CONFIRMATION:
        raise WgpuRtError(f"--frames {args.frames}: {len(frames):,} output files; render at most "
                          f"{FRAMES_WITHOUT_CONFIRMATION:,} frames per run")
    check_pattern(args.out, frames)
    png = output_path(args.out, frames[0]).suffix.lower() == ".png"
    operator, exposure = display_settings(args, png)
    fused = args.denoise or args.adaptive is not None or args.temporal
    if not args.denoise:
        check_denoiser_flags(args, small_networks=args.adaptive is not None or args.temporal)
    if args.models is not None:
        from pathlib import Path

        if not fused:
            raise WgpuRtError(f"--models {args.models}: no network runs without --denoise, --adaptive or --temporal")
        if not Path(args.models).is_dir():
            raise WgpuRtError(f"--models {args.models}: no such folder")
    if args.spp is not None and args.adaptive is not None:
        raise WgpuRtError("--spp with --adaptive: the adaptive budget sets the samples (mean spp)")
    spp = args.spp if args.spp is not None else (1 if fused else 64)
    # A PNG is the display image alone: neither the HDR colour nor any AOV is read back for it.
    renderer = Renderer(args.scene, spp, size, denoise=args.denoise, adaptive=args.adaptive,
                        temporal=args.temporal, max_depth=args.max_depth, seed=args.seed,
                        aovs=() if png else aovs, tonemap=operator if png else None, exposure=exposure, display="f32",
                        precision=args.precision, mesh=args.mesh, camera=args.camera, animation=args.animation,
                        progress=True, aux_samples=args.aux_samples,
                        hdr=not png, quality=args.quality, models_dir=args.models, **denoiser_options(args))
    mean_spp = args.adaptive if args.adaptive is not None else spp
    for result in renderer.frames(frames):
        path = output_path(args.out, result.frame)
        if png:
            write_png(path, result.image[..., :3])
        else:
            write_exr(path, result.color, result.aovs,
                      attributes={AUX_SAMPLES_ATTRIBUTE: renderer.pipeline.aux_samples} if "albedo" in aovs else None)
        stages = ", ".join(f"{name} {ms:.1f} ms" for name, ms in result.stage_ms.items())
        setup = f" after {result.setup_seconds:.2f} s of set-up" if result.setup_seconds else ""
        print(f"{path}: {size[0]}x{size[1]}, {mean_spp:g} spp, {result.seconds:.2f} s{setup} "
              f"({result.samples_per_second / 1e6:.2f} M samples/s)" + (f"; GPU {stages}" if stages else ""))
    return 0
