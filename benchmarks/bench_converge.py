"""Fitting the converge blend: how a frame of n spp mixes its raw mean with the denoised frame of it.

For each scene and n this prints the PSNR (wgpu_rt.metrics: x/(1+x), gamma 2.2) against gold of the raw
mean (brute force at the same spp), the denoised mean, the blend mix(denoised, mean, n / (n + k)) for each
constant k, the n-only rule that shipped before (k = max(32, 2048 / n)) and the shipped per-pixel rule
(wgpu_rt.frame.converge: the mean's error, from how its first half and the whole differ, against the
denoiser's, capped at n² / (n² + CAP_SCALE), squared differences weighed by how they show on screen and
neighbours by how alike they look, in a (2·CONVERGE_RADIUS + 1)² window; the
first half is a render of n // 2 spp with the same seed, the very samples the pipeline copies), and that
rule as it was before BENCHMARKS.md §11 ("linear": a 5×5 window of unweighed sums). Then, for each
blend, its mean PSNR, its mean loss to the best constant k of each row, its worst row against the raw
mean (issue 12 wants ≥ 0) and how many rows are below it, and whether the shipped rule's PSNR rises
with n in every scene. --radius and --cap-scale try other settings of the per-pixel rule.
--pass-cost times the shipped pass alone on this adapter instead: the kernel at --size on a frame of 16 spp
(device timestamps, median of --repeats; BENCHMARKS.md §43 priced its 15×15 window so).
Denoiser: the model in --models (numpy packing, our WGSL engine); gold: our own render at --gold-spp
(--gold-cache shares it with the other benchmarks).

    python3 benchmarks/bench_converge.py [--scenes cornell cornell-glossy sun-room world-2147483648 ...]
        [--size 64x64] [--spp 2 4 8 16 64 256] [--k 8 32 128 512 2048] [--radius 2] [--cap-scale 1024]
        [--gold-spp 4096] [--gold-cache DIR] [--models DIR]
    python3 benchmarks/bench_converge.py --pass-cost --size 1920x1080 [--repeats 7]
"""

from __future__ import annotations

import argparse

import numpy as np
from common import (add_gold_arguments, add_model_arguments, denoiser_options, device_ms, gold_render, image_size,
                    load_scenes, print_header, print_table, resolve_models)

from wgpu_rt import metrics
from wgpu_rt.frame.converge import CONVERGE_CAP_SCALE, CONVERGE_RADIUS, converge, half_count
from wgpu_rt.frame.denoise import denoise, load_model
from wgpu_rt.renderer import render


def parse_args():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["cornell", "cornell-glossy", "sun-room"])
    parser.add_argument("--size", type=image_size, default="64x64")
    parser.add_argument("--spp", type=int, nargs="+", default=[2, 4, 8, 16, 64, 256])
    parser.add_argument("--k", type=float, nargs="+", default=[8, 32, 128, 512, 2048])
    parser.add_argument("--radius", type=int, default=CONVERGE_RADIUS)
    parser.add_argument("--cap-scale", type=float, default=CONVERGE_CAP_SCALE)
    parser.add_argument("--max-depth", type=int, default=8)
    parser.add_argument("--pass-cost", action="store_true",
                        help="time the shipped converge pass alone at --size instead of fitting (needs timestamps)")
    parser.add_argument("--repeats", type=int, default=7, help="timed passes with --pass-cost")
    add_gold_arguments(parser, default_spp=4096)
    add_model_arguments(parser)
    return parser.parse_args()


def mix(denoised, mean, weight):
    return denoised + weight * (mean - denoised)


def pass_cost(size: tuple[int, int], repeats: int) -> float:
    """Median device ms of the shipped converge pass on a (width, height) frame of 16 spp whose denoised
    frame, mean and half mean are random (the pass's work does not depend on the values)."""
    from wgpu_rt.frame.adaptive import HALF_RADIANCE
    from wgpu_rt.frame.converge import HALF_SPP, ConvergePass
    from wgpu_rt.frame.pipeline import StageTimer
    from wgpu_rt.frame.planes import DENOISED, write_plane
    from wgpu_rt.gpu import get_context
    from wgpu_rt.passes import RADIANCE, SPP, FrameBuffers

    ctx = get_context()
    if not ctx.has_timestamps:
        raise SystemExit("--pass-cost needs timestamp queries, which this adapter lacks")
    width, height = size
    rng = np.random.default_rng(0)
    buffers = FrameBuffers(ctx, width, height)
    mean = rng.gamma(2.0, 0.3, (height, width, 3)).astype(np.float32)
    for plane, image in ((DENOISED, mean * 1.1), (RADIANCE, mean), (HALF_RADIANCE, mean * 0.9)):
        write_plane(buffers, plane, image)
    write_plane(buffers, SPP, np.full((height, width), 16, np.uint32))
    write_plane(buffers, HALF_SPP, np.full((height, width), 8, np.uint32))
    converge_pass, timer = ConvergePass(ctx, width, height), StageTimer(ctx, capacity=2)
    times = [device_ms(ctx, timer, lambda encoder: converge_pass.execute(encoder, buffers))
             for _ in range(repeats + 1)]   # the first compiles the kernel
    return float(np.median(times[1:]))


def main() -> None:
    args = parse_args()
    if args.pass_cost:
        print_header(args)
        print(f"converge pass at {args.size[0]}x{args.size[1]} (window {2 * CONVERGE_RADIUS + 1}², cap scale "
              f"{CONVERGE_CAP_SCALE:g}): {pass_cost(args.size, args.repeats):.2f} ms, median of {args.repeats}")
        return
    resolve_models(args)
    print_header(args)
    size = args.size
    model = load_model("denoiser", args.precision, args.models)
    names = [*(f"k={k:g}" for k in args.k), "n-only", "linear", "per-pixel"]
    losses, above_raw, falls, psnrs = [], [], [], []
    for scene in load_scenes(args.scenes):
        gold = gold_render(scene, size, args)
        rows = []
        for n in args.spp:
            noisy = render(scene, spp=n, size=size, max_depth=args.max_depth, seed=77,
                           aovs=("albedo", "normal", "depth"))
            mean = noisy.color
            first = half_count(n)
            half = render(scene, spp=first, size=size, max_depth=args.max_depth, seed=77, aovs=()).color
            denoised = denoise(model, mean, *(noisy.aovs[name] for name in ("albedo", "normal", "depth")), n,
                               **denoiser_options(args))
            constant = [metrics.psnr(gold, mix(denoised, mean, n / (n + k))) for k in args.k]
            n_only = metrics.psnr(gold, mix(denoised, mean, n / (n + max(32.0, 2048.0 / n))))
            counts, first_counts = np.full(size[::-1], n), np.full(size[::-1], first)
            before = converge(denoised, mean, counts, half, first_counts, radius=2, cap_scale=args.cap_scale,
                              on_screen=False, tau=np.inf)
            linear, per_pixel = (metrics.psnr(gold, image) for image in (
                before, converge(denoised, mean, counts, half, first_counts, args.radius, args.cap_scale)))
            blends = np.array([*constant, n_only, linear, per_pixel])
            raw = metrics.psnr(gold, mean)
            losses.append(max(constant) - blends)
            above_raw.append(blends - raw)
            psnrs.append(blends)
            rows.append([n, raw, metrics.psnr(gold, denoised), *blends])
        falls += [f"{scene.name} {a[0]}→{b[0]} spp {b[-1] - a[-1]:+.2f} dB" for a, b in zip(rows, rows[1:])
                  if b[-1] < a[-1]]
        print_table(f"{scene.name} at {size[0]}x{size[1]}: PSNR dB against {args.gold_spp}-spp gold",
                    ["spp", "raw mean", "denoised", *names], rows)
    print_table("mean PSNR over all rows (dB)", names, [list(np.mean(psnrs, axis=0))])
    print_table("mean PSNR loss to each row's best constant k (all scenes and spp; < 0: better than it)", names,
                [list(np.mean(losses, axis=0))])
    print_table("worst row against brute force at the same spp (dB)", names, [list(np.min(above_raw, axis=0))])
    print_table("rows below brute force at the same spp", names, [list(np.sum(np.array(above_raw) < 0, axis=0))])
    print("per-pixel rule: PSNR falls with spp in " + ("; ".join(falls) if falls else "no scene"))


if __name__ == "__main__":
    main()
