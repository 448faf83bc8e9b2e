"""What a denoiser does to a render that has already converged: its quality ceiling. Each scene is rendered
at --input-spp (seed 54321) and handed, with its aux-pass albedo, normal and depth, to ours (told each of
--told samples a pixel; the chain's steps as its flags set them) and to OIDN; each result is scored against
an independent gold (--gold-spp, seed 12345). The input as it is gives the floor: the two renders' own
noise. A denoiser that keeps a clean image scores at or above it; where ours scores below it, no number of
samples can take ours higher, which is what limits it from 16 spp on (BENCHMARKS.md §39).

    python3 benchmarks/bench_passthrough.py --size 256 --input-spp 1024 --gold-spp 1024 --told 16 64 \
        --gold-cache /tmp/gold --scenes cornell painted world-2147483652
"""

from __future__ import annotations

import argparse

from common import (GOLD_TWIN_SEED, add_gold_arguments, add_model_arguments, denoiser_options, errors, gold_render,
                    load_scenes, oidn, parse_with_quick_defaults, print_header, print_table, resolve_models)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["cornell", "cornell-glossy", "sun-room"])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--input-spp", type=int, default=1024, help="samples a pixel of the converged input")
    parser.add_argument("--told", type=int, nargs="+", default=[16, 64],
                        help="the sample counts our network is told the input holds")
    parser.add_argument("--max-depth", type=int, default=8)
    parser.add_argument("--oidn-quality", choices=["balanced", "high"], default="balanced")
    add_gold_arguments(parser, 1024)
    add_model_arguments(parser)
    args = parse_with_quick_defaults(parser, {"size": 32, "input_spp": 64, "gold_spp": 64, "told": [16]})
    resolve_models(args)
    print_header(args)
    from wgpu_rt.frame.denoise import denoise, load_model
    from wgpu_rt.renderer import Renderer
    from wgpu_rt.trace.trace_pass import AUX_SAMPLES

    model = load_model("denoiser", args.precision, models_dir=args.models)
    size = (args.size, args.size)
    rows = []
    for scene in load_scenes(args.scenes):
        gold = gold_render(scene, size, args)
        converged = gold_render(scene, size, args, seed=GOLD_TWIN_SEED, spp=args.input_spp)
        aux = next(Renderer(scene, 1, aovs=("albedo", "normal", "depth"), aux_samples=AUX_SAMPLES, size=size,
                            max_depth=args.max_depth, seed=7).frames()).aovs
        guides = (aux["albedo"], aux["normal"], aux["depth"])
        images = {"the input as it is": converged}
        for told in args.told:
            images[f"ours, told {told} spp"] = denoise(model, converged, *guides, told, **denoiser_options(args))
        images[f"OIDN {args.oidn_quality}"] = oidn(converged, aux["albedo"], aux["normal"], args.oidn_quality)
        rows += [[scene.name, name, errors(gold, image)["PSNR"]] for name, image in images.items()]
    print_table(f"PSNR (dB) of a {args.input_spp}-spp render, denoised, against an independent {args.gold_spp}-spp "
                f"gold, {args.size}²", ["scene", "image", "PSNR"], rows)


if __name__ == "__main__":
    main()
