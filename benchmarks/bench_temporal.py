"""Temporal stability on animated scenes, and accumulation under a static camera.

On each of --scenes (default ``moving``, whose camera and a box move every frame; ``world-SEED``: a generated
world with its camera orbiting and one object drifting), for per-frame ours (1 spp + denoiser), per-frame
OIDN (pyoidn, hdr=True, albedo + normal, on our 1-spp frames) and temporal ours (the fused pipeline
with reprojection, clamping and the Confidence Predictor when the models folder has one):
- flicker: mean |Δ| between consecutive output frames, on display values (Reinhard + gamma 2.2, as
  wgpu_rt.metrics' PSNR), minus the same for the gold sequence (0 = as steady as the truth);
- ghosting: relMSE over disoccluded pixels only (where the warped previous gold frame disagrees with
  the current one: wgpu_rt.train.targets.disocclusion_mask, the Confidence Predictor's target);
- relMSE over all pixels, for context.
On a static camera (``cornell``): PSNR of the temporal output after --static-frames frames (the tracer
accumulates 1 spp per frame, the mean is denoised and blended with itself by spp) minus the PSNR of one
denoised frame. Gold: our own render of each frame at --gold-spp (Mitsuba's with --gold-renderer mitsuba,
the motion vectors still ours). --stops adds rows of temporal ours on each scene with 2^stops times its light
(``Scene.with_light_scaled``: the scene in other units, which renders exactly scaled), divided back before
scoring: a pipeline that reads every scale alike repeats the first row.

    python3 benchmarks/bench_temporal.py [--quick] [--scenes moving world-SEED ...] [--size 96x96] [--frames 16]
        [--gold-spp 4096] [--gold-cache DIR] [--gold-renderer ours|mitsuba] [--static-frames 16]
        [--clamp none|box|variance] [--gamma 1.0] [--stops -8 8]
        [--models DIR | --seed-models]
"""

from __future__ import annotations

import argparse

import numpy as np
from common import (add_gold_arguments, add_model_arguments, gold_frame, gold_render, hdr_pipeline, image_size,
                    linear_frame, load_scenes, oidn, parse_with_quick_defaults, print_header, print_table,
                    resolve_models)

from wgpu_rt import metrics
from wgpu_rt.frame.temporal import CLAMP_MODES, TemporalSettings
from wgpu_rt.renderer import render
from wgpu_rt.trace.trace_pass import AUX_SAMPLES
from wgpu_rt.train.targets import disocclusion_mask

QUICK = {"size": "32x32", "frames": 8, "gold_spp": 1024, "static_frames": 16}


def parse_args():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["moving"],
                        help="animated scenes: built-ins, scene files, or world-SEED (a generated world, its camera "
                             "and one object moving over --frames frames); a mean row follows when there are several")
    parser.add_argument("--static-scene", default="cornell",
                        help="a built-in scene, a scene file or world-SEED (a generated world)")
    parser.add_argument("--size", type=image_size, default="96x96")
    parser.add_argument("--frames", type=int, default=16)
    parser.add_argument("--static-frames", type=int, default=16, help="0: no static-camera run")
    add_gold_arguments(parser, default_spp=4096)
    parser.add_argument("--max-depth", type=int, default=8)
    parser.add_argument("--clamp", choices=CLAMP_MODES, default=TemporalSettings.clamp,
                        help="history clamp of the temporal runs (default: the pipeline's)")
    parser.add_argument("--gamma", type=float, default=TemporalSettings.gamma,
                        help="variance-box width in standard deviations (default: the pipeline's)")
    parser.add_argument("--confidence-floor", type=float, default=TemporalSettings.confidence_floor,
                        help="confidence at or below which no history is kept (default: the pipeline's)")
    parser.add_argument("--stops", type=float, nargs="*", default=[],
                        help="also run temporal ours with 2^stops times the light, one row each")
    add_model_arguments(parser)
    return parse_with_quick_defaults(parser, QUICK)


def flicker(sequence) -> float:
    display = [metrics.to_display(frame) for frame in sequence]
    return float(np.mean([np.abs(b - a).mean() for a, b in zip(display, display[1:])]))


def masked_rel_mse(reference, image, mask) -> float | None:
    if not mask.any():
        return None
    error = (image - reference) ** 2 / (reference ** 2 + metrics.REL_MSE_EPSILON)
    return float(error[mask > 0].mean())


def main() -> None:
    args = parse_args()
    resolve_models(args)
    print_header(args)
    settings = TemporalSettings(clamp=args.clamp, gamma=args.gamma, confidence_floor=args.confidence_floor)
    means = {}
    scenes = load_scenes(args.scenes, world_frames=args.frames)
    for scene in scenes:
        for name, row in animated_rows(scene, args, settings).items():
            means.setdefault(name, []).append(row)
    if len(scenes) > 1:
        print_table(f"mean over the {len(scenes)} animated scenes (ghosting: over those with disoccluded pixels)",
                    ["method", "flicker", "ghosting relMSE", "relMSE"],
                    [[name, *(mean_of_finite(column) for column in zip(*rows))] for name, rows in means.items()])
    if args.static_frames > 0:
        static_accumulation(args, settings)


def mean_of_finite(values) -> float | None:
    """The mean of the finite values (a scene without disoccluded pixels has no ghosting); None if none is."""
    finite = [v for v in values if np.isfinite(v)]
    return float(np.mean(finite)) if finite else None


def animated_rows(scene, args, settings) -> dict[str, list[float]]:
    """Score each method on ``scene``'s frames (printing the table); {method: [flicker, ghosting, relMSE]}."""
    size = args.size
    frames = range(min(args.frames, scene.frame_count))
    print(f"{scene.name}: {len(frames)} frames at {size[0]}x{size[1]}, gold {args.gold_spp} spp"
          f"{' (Mitsuba)' if args.gold_renderer == 'mitsuba' else ''}, max depth {args.max_depth}")

    gold, motion = zip(*(gold_frame(scene, size, args, f) for f in frames))
    masks = [np.zeros(size[::-1], np.float32)] + [
        disocclusion_mask(gold[t - 1], gold[t], motion[t]) for t in range(1, len(gold))]

    def noisy_oidn(frame):
        one = render(scene, spp=1, size=size, max_depth=args.max_depth, seed=0, frames=frame,
                     aovs=("albedo", "normal"), aux_samples=AUX_SAMPLES)   # the albedo ours gets
        return oidn(one.color, one.aovs["albedo"], one.aovs["normal"])

    per_frame = hdr_pipeline(scene, size, args, denoise=True)
    temporal = hdr_pipeline(scene, size, args, denoise=True, temporal=settings)
    print("temporal confidence network: " + ("yes" if temporal.pipeline.temporal.confidence else "no (none in models)"))
    sequences = {"per-frame ours": [linear_frame(per_frame, f) for f in frames],
                 "per-frame OIDN": [noisy_oidn(f) for f in frames],
                 "temporal ours": [linear_frame(temporal, f) for f in frames]}
    for stops in args.stops:
        scale = np.float32(2.0 ** stops)
        lit = hdr_pipeline(scene.with_light_scaled(scale), size, args, denoise=True, temporal=settings)
        sequences[f"temporal ours at {stops:+g} stops"] = [linear_frame(lit, f) / scale for f in frames]
    gold_flicker = flicker(gold)
    rows, ghosting_by_frame = {}, {}
    for name, sequence in sequences.items():
        ghosting = [masked_rel_mse(g, o, m) for g, o, m in zip(gold[1:], sequence[1:], masks[1:])]
        ghosting = ghosting_by_frame[name] = [v for v in ghosting if v is not None]
        rows[name] = [flicker(sequence) - gold_flicker, float(np.mean(ghosting)) if ghosting else float("nan"),
                      float(np.mean([metrics.rel_mse(g, o) for g, o in zip(gold, sequence)]))]
    print_table(f"{scene.name}: flicker (gold's own {gold_flicker:.4g} subtracted), ghosting, error "
                f"(disoccluded: {np.mean([m.mean() for m in masks[1:]]):.1%} of pixels)",
                ["method", "flicker", "ghosting relMSE", "relMSE"],
                [[name, *(v if np.isfinite(v) else None for v in row)] for name, row in rows.items()])

    difference = np.subtract(ghosting_by_frame["temporal ours"], ghosting_by_frame["per-frame ours"])
    if len(difference) > 1:   # paired by frame: is temporal's disocclusion error really above per-frame's?
        print(f"ghosting, temporal − per-frame ours: {difference.mean():+.4f} ± "
              f"{difference.std(ddof=1) / np.sqrt(len(difference)):.4f} (mean ± standard error over "
              f"{len(difference)} frames)")
    return rows


def static_accumulation(args, settings) -> None:
    """The static camera's table: --static-frames temporal frames of --static-scene against one denoised frame."""
    size = args.size
    (static,) = load_scenes([args.static_scene])
    static_gold = gold_render(static, size, args)
    single = linear_frame(hdr_pipeline(static, size, args, denoise=True), 0)
    accumulating = hdr_pipeline(static, size, args, denoise=True, temporal=settings)
    accumulated = [linear_frame(accumulating, f) for f in range(args.static_frames)][-1]
    single_psnr, accumulated_psnr = metrics.psnr(static_gold, single), metrics.psnr(static_gold, accumulated)
    print_table(f"{static.name} (static camera): {args.static_frames} temporal frames vs one denoised frame",
                ["output", "PSNR dB"], [["one denoised frame", single_psnr],
                                        [f"temporal, frame {args.static_frames}", accumulated_psnr],
                                        ["gain", accumulated_psnr - single_psnr]])


if __name__ == "__main__":
    main()
