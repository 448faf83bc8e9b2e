"""Denoised quality against the sample count: PSNR (x/(1+x), gamma 2.2) of brute force, ours and OIDN
at each spp, on the same noisy renders, against a gold render. Issue 12's bar: ours rises with spp and
never falls below brute force at the same spp.

    python3 benchmarks/bench_spp.py --size 96 --spp 1 2 4 16 64 256 --gold-spp 4096 [--scenes ...] [--quality high]
    python3 benchmarks/bench_spp.py --size 256 --spp 1 4 --gold-renderer mitsuba --gold-spp 8192 \
        --oidn-quality balanced --scenes benchmarks/scenes/*.toml     # issue 12's scenes as a user builds them
"""

from __future__ import annotations

import argparse

from common import (GOLD_TWIN_SEED, add_gold_arguments, add_model_arguments, errors, gold_render, load_scenes,
                    denoiser_options, oidn, parse_with_quick_defaults, print_header, print_table, resolve_models,
                    twin_corrected_psnr)


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
    parser.add_argument("--oidn-quality", choices=["balanced", "high"], default="high",
                        help="OIDN's quality (issue 12's per-scene bar is against balanced)")
    add_gold_arguments(parser, 4096)
    add_model_arguments(parser)
    args = parse_with_quick_defaults(parser, {"size": 48, "spp": [1, 4, 16], "gold_spp": 512})
    resolve_models(args)
    print_header(args)
    from wgpu_rt.renderer import Renderer
    from wgpu_rt.trace.trace_pass import AUX_SAMPLES

    size = (args.size, args.size)
    rows = []
    for scene in load_scenes(args.scenes):
        gold = gold_render(scene, size, args)
        twin = gold_render(scene, size, args, seed=GOLD_TWIN_SEED) if args.gold_twin else None
        for spp in args.spp:
            scores = {"brute": [], "ours": [], "oidn": []}
            for seed in range(7, 7 + args.seeds):
                options = dict(size=size, max_depth=args.max_depth, seed=seed, models_dir=args.models,
                               precision=args.precision)
                noisy = next(Renderer(scene, spp, aovs=("albedo", "normal"), aux_samples=AUX_SAMPLES,
                                       **options).frames())   # OIDN gets the albedo ours gets
                ours = next(Renderer(scene, spp, denoise=True, aovs=(), quality=args.quality, **denoiser_options(args),
                                     **options).frames()).color
                theirs = oidn(noisy.color, noisy.aovs["albedo"], noisy.aovs["normal"], args.oidn_quality)
                for name, image in (("brute", noisy.color), ("ours", ours), ("oidn", theirs)):
                    scores[name].append(errors(gold, image)["PSNR"] if twin is None
                                        else twin_corrected_psnr(gold, twin, image))
            psnr = {name: sum(values) / len(values) for name, values in scores.items()}
            rows.append([scene.name, spp, psnr["brute"], psnr["ours"], psnr["oidn"],
                         psnr["ours"] - psnr["brute"], psnr["ours"] - psnr["oidn"]])
    gold = f"{args.gold_spp}-spp gold" + (" of Mitsuba" if args.gold_renderer == "mitsuba" else "")
    against = f"the truth as two {gold}s estimate it (--gold-twin)" if args.gold_twin else gold
    print_table(f"PSNR (dB) against {against}, {args.size}², ours {args.quality}, OIDN {args.oidn_quality}, "
                "same noisy input for all"
                + (f", mean of {args.seeds} noise seeds" if args.seeds > 1 else ""),
                ["scene", "spp", "brute force", "ours", "OIDN", "ours − brute", "ours − OIDN"], rows)


if __name__ == "__main__":
    main()
