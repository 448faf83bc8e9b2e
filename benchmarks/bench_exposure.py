"""How a denoiser's result depends on the scale of the light: each scene is rendered once per noise seed
(colour, aux-pass albedo, normal, depth), the colour multiplied by 2^stops for each of --stops, denoised
by ours with the exposure step on and off (``denoise()`` as `wgpu-rt denoise` runs it, with the steps'
flags: no hand-over to the samples' mean) and by OIDN, divided back by 2^stops and scored against the
scene's gold. A denoiser that reads every scale alike gives one PSNR along a row; the renderer's own units
are 0 stops (BENCHMARKS.md §40).

    python3 benchmarks/bench_exposure.py --size 256 --spp 1 4 16 --seeds 2 --stops -8 -4 -2 0 2 4 8 \
        --gold-cache /tmp/gold --scenes cornell sun-room world-2147483652
"""

from __future__ import annotations

import argparse

import numpy as np
from common import (add_gold_arguments, add_model_arguments, denoiser_options, errors, gold_render, load_scenes, oidn,
                    parse_with_quick_defaults, print_header, print_table, resolve_models)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["cornell", "cornell-glossy", "sun-room"])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--spp", type=int, nargs="+", default=[1, 4, 16])
    parser.add_argument("--stops", type=float, nargs="+", default=[-8, -4, -2, 0, 2, 4, 8],
                        help="the scales of the light, in stops from the renderer's own")
    parser.add_argument("--seeds", type=int, default=1, help="noisy renders per row (seeds 7, 8, …), mean PSNR")
    parser.add_argument("--max-depth", type=int, default=8)
    parser.add_argument("--oidn-quality", choices=["balanced", "high"], default="balanced")
    add_gold_arguments(parser, 1024)
    add_model_arguments(parser)
    args = parse_with_quick_defaults(parser, {"size": 32, "spp": [1], "stops": [-4, 0], "gold_spp": 64})
    resolve_models(args)
    print_header(args)
    from wgpu_rt.frame.denoise import denoise, load_model
    from wgpu_rt.renderer import Renderer
    from wgpu_rt.trace.trace_pass import AUX_SAMPLES

    model = load_model("denoiser", args.precision, models_dir=args.models)
    size = (args.size, args.size)
    methods = {"ours, exposure step": True, "ours, without it": False, f"OIDN {args.oidn_quality}": None}
    options = denoiser_options(args)   # --auto-exposure is what each row of ours sets
    rows = []
    for scene in load_scenes(args.scenes):
        gold = gold_render(scene, size, args)
        for spp in args.spp:
            scores = {(name, stops): [] for name in methods for stops in args.stops}
            for seed in range(7, 7 + args.seeds):
                frame = next(Renderer(scene, spp, aovs=("albedo", "normal", "depth"), aux_samples=AUX_SAMPLES,
                                      size=size, max_depth=args.max_depth, seed=seed).frames())
                aux = frame.aovs
                for stops in args.stops:
                    scale = np.float32(2.0 ** stops)
                    for name, auto in methods.items():
                        if auto is None:
                            image = oidn(frame.color * scale, aux["albedo"], aux["normal"], args.oidn_quality)
                        else:
                            image = denoise(model, frame.color * scale, aux["albedo"], aux["normal"], aux["depth"],
                                            spp, **{**options, "auto_exposure": auto})
                        scores[name, stops].append(errors(gold, image / scale)["PSNR"])
            for name in methods:
                psnr = [float(np.mean(scores[name, stops])) for stops in args.stops]
                rows.append([scene.name, spp, name, *psnr, max(psnr) - min(psnr)])
    print_table(f"PSNR (dB) against {args.gold_spp}-spp gold, {args.size}², the light scaled by 2^stops and the "
                f"result scaled back, mean of {args.seeds} noise seed(s)",
                ["scene", "spp", "denoiser", *(f"{stops:+g}" for stops in args.stops), "spread"], rows)


if __name__ == "__main__":
    main()
