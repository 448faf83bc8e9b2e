"""Denoising another renderer's EXR: Mitsuba 3 renders each scene at a few spp with its AOV integrator
(albedo, shading normal, depth) and writes the multi-layer EXR a Mitsuba user has; `wgpu-rt denoise --layer …`
denoises that file, OIDN balanced the same colour, albedo and normal; PSNR (x/(1+x), gamma 2.2) against
Mitsuba's own gold. Beside them, ours on our own render of the same scene at the same spp (albedo from our aux
pass, noise-free behind glass), which shows what a foreign file's inputs cost the network, and ours on the file
with its point-sampled albedo as it is (`--albedo-samples 0`), which shows what smoothing it buys.

    python3 benchmarks/bench_other_renderer.py --size 256 --spp 1 4 --seeds 2 --gold-spp 4096 --gold-cache /tmp/gold \
        --scenes cornell cornell-glossy sun-room benchmarks/scenes/*.toml
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from common import (add_gold_arguments, add_model_arguments, denoise_exr, denoiser_options, errors, gold_render,
                    load_scenes, mitsuba, oidn, parse_with_quick_defaults, print_header, print_table, resolve_models)

# How Mitsuba's AOV integrator names the layers (aovs="albedo:albedo,nn:sh_normal,dd:depth"): its colour is
# the file's top-level R, G, B, its depth the distance along the camera ray, 0 where nothing was hit.
MITSUBA_AOVS = "albedo:albedo,nn:sh_normal,dd:depth"
LAYER_FLAGS = ["--layer", "albedo=albedo", "--layer", "normal=nn", "--layer", "depth=dd"]


def mitsuba_exr(mi, scene, size, spp: int, max_depth: int, seed: int, path: Path) -> None:
    """Mitsuba's render of ``scene`` with its albedo, normal and depth AOVs, written by Mitsuba to ``path``."""
    from wgpu_rt.scene.mitsuba import to_mitsuba

    description = to_mitsuba(scene, size[0], size[1], spp, max_depth, seed=seed)
    description["integrator"] = {"type": "aov", "aovs": MITSUBA_AOVS, "image": description["integrator"]}
    loaded = mi.load_dict(description)
    mi.render(loaded, spp=spp, seed=seed)
    loaded.sensors()[0].film().bitmap().write(str(path))


def denoise_file(path: Path, out: Path, spp: int, args, *extra: str) -> np.ndarray:
    """`wgpu-rt denoise PATH --layer … EXTRA` as a user runs it; the denoised top-level colour."""
    steps = ["--white-balance", args.white_balance, "--low-band", args.low_band, "--chroma", args.chroma,
             "--post-filter", args.post_filter]
    return denoise_exr(path, out, args, "--spp", str(spp), *LAYER_FLAGS, *extra, *steps)["color"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["cornell", "cornell-glossy", "sun-room"])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--spp", type=int, nargs="+", default=[1, 4])
    parser.add_argument("--max-depth", type=int, default=8)
    parser.add_argument("--seeds", type=int, default=1, help="noisy renders per row (seeds 7, 8, …); mean PSNR")
    add_gold_arguments(parser, 4096)
    add_model_arguments(parser)
    args = parse_with_quick_defaults(parser, {"size": 48, "spp": [1, 4], "gold_spp": 256})
    args.gold_renderer = "mitsuba"   # the gold is the other renderer's too
    resolve_models(args)
    print_header(args)
    from wgpu_rt.io import read_exr
    from wgpu_rt.renderer import Renderer

    mi, variant = mitsuba()
    print(f"Mitsuba variant: {variant}")
    size = (args.size, args.size)
    names = ["Mitsuba, noisy", "ours on Mitsuba's EXR", "OIDN balanced on it", "ours on our own render",
             "ours, its albedo unsmoothed"]
    rows = []
    with tempfile.TemporaryDirectory(prefix="wgpu-rt-other-renderer-") as folder:
        for scene in load_scenes(args.scenes):
            gold = gold_render(scene, size, args)
            for spp in args.spp:
                scores = {name: [] for name in names}
                for seed in range(7, 7 + args.seeds):
                    path = Path(folder) / f"{scene.name}_{spp}_{seed}.exr"
                    mitsuba_exr(mi, scene, size, spp, args.max_depth, seed, path)
                    layers = read_exr(path)
                    ours_own = next(Renderer(scene, spp, denoise=True, aovs=(), size=size, max_depth=args.max_depth,
                                             seed=seed, models_dir=args.models, precision=args.precision,
                                             **denoiser_options(args)).frames()).color
                    images = [layers["color"], denoise_file(path, path.with_suffix(".out.exr"), spp, args),
                              oidn(layers["color"], layers["albedo"], layers["nn"], "balanced"), ours_own,
                              denoise_file(path, path.with_suffix(".raw.exr"), spp, args, "--albedo-samples", "0")]
                    for name, image in zip(names, images):
                        scores[name].append(errors(gold, image)["PSNR"])
                psnr = [float(np.mean(scores[name])) for name in names]
                rows.append([scene.name, spp, *psnr[:4], psnr[1] - psnr[2], psnr[1] - psnr[3], psnr[4]])
    print_table(f"PSNR (dB) against Mitsuba's {args.gold_spp}-spp gold, {args.size}², mean of {args.seeds} seed(s)",
                ["scene", "spp", *names[:4], "ours − OIDN (Mitsuba's EXR)", "ours: Mitsuba's EXR − own render",
                 names[4]], rows)


if __name__ == "__main__":
    main()
