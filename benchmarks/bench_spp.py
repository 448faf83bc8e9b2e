"""Denoised quality against the sample count: PSNR (x/(1+x), gamma 2.2) of brute force, ours and OIDN
at each spp, on the same noisy renders, against a gold render. Issue 12's bar: ours rises with spp and
never falls below brute force at the same spp.

    python3 benchmarks/bench_spp.py --size 96 --spp 1 2 4 16 64 256 --gold-spp 4096 [--scenes ...] [--quality high]
    python3 benchmarks/bench_spp.py --size 256 --spp 1 4 --gold-renderer mitsuba --gold-spp 8192 \
        --oidn-quality balanced --scenes benchmarks/scenes/*.toml     # issue 12's scenes as a user builds them
    python3 benchmarks/bench_spp.py --size 256 --spp 1 4 --seeds 2 --oidn-quality balanced high --all-metrics \
        --brute-spp 16 64 256 --scenes world-2147483648 …   # issue 12's measurement of record
    python3 benchmarks/bench_spp.py … --lens 0.02    # the same scenes through a thin lens (depth of field)

--oidn-quality takes one or more qualities; "ours − OIDN" is against the first. --all-metrics adds a table of
PSNR, SSIM, FLIP and relMSE for brute force, ours and each OIDN quality (means over the seeds), with each
one's equivalent spp: the sample count at which brute force reaches its relMSE, interpolated in log-log on
the brute-force curve of --spp and --brute-spp (brute-force renders only, same seeds).
"""

from __future__ import annotations

import argparse

import numpy as np
from common import (GOLD_TWIN_SEED, add_gold_arguments, add_model_arguments, denoiser_options, equivalent_spp, errors,
                    gold_render, load_scenes, oidn, parse_with_quick_defaults, print_header, print_table,
                    resolve_models, twin_corrected_psnr)

from wgpu_rt import metrics


def through_lens(scene, fraction: float) -> None:
    """``scene`` seen through a thin lens: each camera (and keyframe) gets an aperture radius of ``fraction``
    times its distance to its target and focuses on the target; the name gains "+lens{fraction}"."""
    for camera in [scene.camera, *scene.camera_keyframes.values()]:
        distance = float(np.linalg.norm(camera.target.astype(np.float64) - camera.origin))
        camera.aperture_radius, camera.focus_distance = fraction * distance, distance
    scene.name += f"+lens{fraction:g}"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["cornell", "cornell-glossy", "sun-room"])
    parser.add_argument("--size", type=int, default=96)
    parser.add_argument("--spp", type=int, nargs="+", default=[1, 2, 4, 16, 64, 256])
    parser.add_argument("--max-depth", type=int, default=8)
    parser.add_argument("--seeds", type=int, default=1,
                        help="noisy renders per row (seeds 7, 8, …); the table shows their mean PSNR, "
                             "since one 64² realization moves a model's score by a few tenths of a dB")
    parser.add_argument("--quality", choices=["balanced", "high"], default="balanced",
                        help="our denoiser's quality (high: an ensemble of 4 turned passes)")
    parser.add_argument("--oidn-quality", choices=["balanced", "high"], nargs="+", default=["high"],
                        help="OIDN's qualities; ours − OIDN is against the first (issue 12's per-scene bar is "
                             "against balanced)")
    parser.add_argument("--all-metrics", action="store_true",
                        help="also a table of PSNR, SSIM, FLIP, relMSE and equivalent spp of every method")
    parser.add_argument("--brute-spp", type=int, nargs="*", default=[],
                        help="brute-force counts added to --spp's for --all-metrics' equivalent spp")
    parser.add_argument("--lens", type=float, default=0.0, metavar="FRACTION",
                        help="see every scene through a thin lens of aperture radius FRACTION times its camera's "
                             "distance to the target, focused on the target (each scene's name gains "
                             "'+lensFRACTION', so its gold is cached apart from the pinhole's)")
    add_gold_arguments(parser, 4096)
    add_model_arguments(parser)
    args = parse_with_quick_defaults(parser, {"size": 48, "spp": [1, 4, 16], "gold_spp": 512})
    resolve_models(args)
    print_header(args)
    from wgpu_rt.renderer import Renderer
    from wgpu_rt.trace.trace_pass import AUX_SAMPLES

    size = (args.size, args.size)
    seeds = range(7, 7 + args.seeds)
    oidn_names = [f"OIDN {quality}" for quality in args.oidn_quality]
    rows, metric_rows = [], []
    for scene in load_scenes(args.scenes):
        if args.lens:
            through_lens(scene, args.lens)
        gold = gold_render(scene, size, args)
        twin = gold_render(scene, size, args, seed=GOLD_TWIN_SEED) if args.gold_twin else None
        measured = {}   # (method, spp) → each seed's metrics
        for spp in args.spp:
            scores = {name: [] for name in ("brute", "ours", *oidn_names)}
            for seed in seeds:
                options = dict(size=size, max_depth=args.max_depth, seed=seed, models_dir=args.models,
                               precision=args.precision)
                noisy = next(Renderer(scene, spp, aovs=("albedo", "normal"), aux_samples=AUX_SAMPLES,
                                       **options).frames())   # OIDN gets the albedo ours gets
                ours = next(Renderer(scene, spp, denoise=True, aovs=(), quality=args.quality, **denoiser_options(args),
                                     **options).frames()).color
                images = {"brute": noisy.color, "ours": ours}
                for name, quality in zip(oidn_names, args.oidn_quality):
                    images[name] = oidn(noisy.color, noisy.aovs["albedo"], noisy.aovs["normal"], quality)
                for name, image in images.items():
                    scores[name].append(errors(gold, image)["PSNR"] if twin is None
                                        else twin_corrected_psnr(gold, twin, image))
                    if args.all_metrics:
                        measured.setdefault((name, spp), []).append(metrics.all_metrics(gold, image))
            psnr = {name: sum(values) / len(values) for name, values in scores.items()}
            rows.append([scene.name, spp, psnr["brute"], psnr["ours"], *(psnr[name] for name in oidn_names),
                         psnr["ours"] - psnr["brute"], psnr["ours"] - psnr[oidn_names[0]]])
        if args.all_metrics:
            metric_rows += metric_table_rows(scene, gold, measured, args, seeds)
    gold = f"{args.gold_spp}-spp gold" + (" of Mitsuba" if args.gold_renderer == "mitsuba" else "")
    against = f"the truth as two {gold}s estimate it (--gold-twin)" if args.gold_twin else gold
    seeds_said = f", mean of {args.seeds} noise seeds" if args.seeds > 1 else ""
    print_table(f"PSNR (dB) against {against}, {args.size}², ours {args.quality}, same noisy input for all"
                + seeds_said, ["scene", "spp", "brute force", "ours", *oidn_names, "ours − brute",
                               f"ours − {oidn_names[0]}"], rows)
    if args.all_metrics:
        print_table(f"Every metric against {gold}, {args.size}²{seeds_said}; equivalent spp: where brute force "
                    "reaches the same relMSE", ["scene", "spp", "method", "PSNR", "SSIM", "FLIP", "relMSE",
                                                "equivalent spp"], metric_rows)


def metric_table_rows(scene, gold, measured: dict, args, seeds) -> list[list]:
    """--all-metrics' rows for one scene: each method at each spp, its metrics' means over the seeds and its
    equivalent spp on the brute-force curve of --spp and --brute-spp (the extra counts rendered here)."""
    from wgpu_rt.renderer import render

    mean = {key: {name: float(np.mean([m.get(name, np.nan) for m in values])) for name in values[0]}
            for key, values in measured.items()}
    brute = {spp: mean[("brute", spp)]["rel_mse"] for spp in args.spp}
    for spp in sorted(set(args.brute_spp) - set(args.spp)):
        brute[spp] = float(np.mean([metrics.rel_mse(gold, render(scene, spp=spp, size=(args.size, args.size),
                                                                 max_depth=args.max_depth, seed=seed, aovs=()).color)
                                    for seed in seeds]))
    curve = sorted(brute)
    return [[scene.name, spp, method, m["psnr"], m["ssim"], m.get("flip", float("nan")), m["rel_mse"],
             equivalent_spp(curve, [brute[n] for n in curve], m["rel_mse"])]
            for (method, spp), m in mean.items()]


if __name__ == "__main__":
    main()
