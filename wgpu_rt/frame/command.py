"""``wgpu-rt render --denoise [--adaptive BUDGET] [--temporal]``: the fused on-device frame pipeline.

The render command (owned by the tracer) hands over to ``run_fused`` when any of these flags is set.
A .png gets the tone-mapped display image; an .exr gets linear HDR colour (no curve, no sRGB).
"""

from __future__ import annotations


def add_arguments(parser) -> None:
    parser.add_argument("--denoise", action="store_true",
                        help="denoise 1-spp frames on the device with models/denoiser.onnx")
    parser.add_argument("--adaptive", type=float, metavar="BUDGET",
                        help="adaptive sampling guided by models/error_predictor.onnx at BUDGET mean spp")
    parser.add_argument("--temporal", action="store_true",
                        help="temporal accumulation over --frames (reprojection, clamping, confidence)")


def wants_fused(args) -> bool:
    return bool(args.denoise or args.adaptive is not None or args.temporal)


def run_fused(args) -> int:
    import time

    from ..commands.render import output_paths, parse_frames
    from ..io import write_exr, write_png
    from ..render import parse_size
    from ..scene import load_scene
    from .pipeline import render_frames

    width, height = parse_size(args.size)
    frames = parse_frames(args.frames)
    paths = output_paths(args.out, frames, args.frames is not None and len(frames) > 1)
    hdr = all(p.suffix.lower() == ".exr" for p in paths)
    scene = load_scene(args.scene, mesh=args.mesh)
    start = time.perf_counter()
    rendered = render_frames(scene, denoise=args.denoise, adaptive=args.adaptive, temporal=args.temporal,
                             frames=frames, width=width, height=height, max_depth=args.max_depth,
                             seed=args.seed, output="f32", operator="none" if hdr else "aces", srgb=not hdr)
    seconds = (time.perf_counter() - start) / len(frames)
    for frame, path in zip(rendered, paths):
        if hdr:
            write_exr(path, frame.image[..., :3])
        else:
            write_png(path, frame.image[..., :3])
        stages = ", ".join(f"{name} {ms:.1f} ms" for name, ms in frame.stage_ms.items())
        print(f"{path}: {width}x{height}, {seconds:.2f} s/frame" + (f" ({stages})" if stages else ""))
    return 0
