"""Fitting the static-camera converge blend: how much weight the raw n-sample mean should get against
the denoised frame of it (TemporalSettings.converge_spp and converge_scale).

A frame of n spp (a render at n spp, or a static camera's n accumulated frames) is shown as
mix(denoised(mean), mean, n / (n + k)). For each scene and n this prints the PSNR (wgpu_rt.metrics:
x/(1+x), gamma 2.2) against gold of the raw mean, the denoised mean, the blend for each constant k and
for the shipped rule (k = max(CONVERGE_SPP, CONVERGE_SCALE / n), wgpu_rt.frame.unpack.converge), then
each blend's mean loss to the best of that row (the number to minimise) and its worst row against the
raw mean (brute force at the same spp; issue 12 wants it ≥ 0).
Denoiser: our WGSL engine on the model in --models; gold: our own render at --gold-spp (--gold-cache
shares it with the other benchmarks).

    python3 benchmarks/bench_converge.py [--scenes cornell cornell-glossy sun-room] [--size 96x96]
        [--spp 1 2 4 8 16 32 64 128] [--k 4 8 16 24 32 64 128] [--gold-spp 8192] [--gold-cache DIR]
        [--models DIR]
"""

from __future__ import annotations

import argparse

import numpy as np
from common import (add_gold_arguments, add_model_arguments, gold_render, load_scenes, print_header,
                    print_table, resolve_models)

from wgpu_rt import metrics
from wgpu_rt.frame.denoise import denoise, load_model
from wgpu_rt.frame.unpack import converge
from wgpu_rt.renderer import parse_size, render


def parse_args():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["cornell", "cornell-glossy", "sun-room"])
    parser.add_argument("--size", default="96x96")
    parser.add_argument("--spp", type=int, nargs="+", default=[1, 2, 4, 8, 16, 32, 64, 128])
    parser.add_argument("--k", type=float, nargs="+", default=[4, 8, 16, 24, 32, 64, 128])
    parser.add_argument("--max-depth", type=int, default=8)
    add_gold_arguments(parser, default_spp=8192)
    add_model_arguments(parser)
    return parser.parse_args()


def main() -> None:
    args = parse_args()
    resolve_models(args)
    print_header(args)
    size = parse_size(args.size)
    model = load_model("denoiser", args.precision, args.models)
    losses, below_brute = [], []   # per (scene, n): each blend's PSNR below the row's best, and above raw
    for scene in load_scenes(args.scenes):
        gold = gold_render(scene, size, args)
        rows = []
        for n in args.spp:
            noisy = render(scene, spp=n, size=size, max_depth=args.max_depth, seed=77,
                           aovs=("albedo", "normal", "depth"))
            denoised = denoise(model, noisy.color, *(noisy.aovs[name] for name in ("albedo", "normal", "depth")), n)
            blends = [metrics.psnr(gold, denoised + n / (n + k) * (noisy.color - denoised)) for k in args.k]
            blends.append(metrics.psnr(gold, converge(denoised, noisy.color, np.full(size[::-1], n))))
            raw = metrics.psnr(gold, noisy.color)
            losses.append(max(blends) - np.array(blends))
            below_brute.append(np.array(blends) - raw)
            rows.append([n, raw, metrics.psnr(gold, denoised), *blends])
        print_table(f"{scene.name} at {size[0]}x{size[1]}: PSNR dB against {args.gold_spp}-spp gold",
                    ["spp", "raw mean", "denoised", *(f"k={k:g}" for k in args.k), "rule"], rows)
    names = [*(f"k={k:g}" for k in args.k), "rule"]
    print_table("mean PSNR loss to each row's best blend (all scenes and spp)", names, [list(np.mean(losses, axis=0))])
    print_table("worst row against brute force at the same spp (dB)", names, [list(np.min(below_brute, axis=0))])


if __name__ == "__main__":
    main()
