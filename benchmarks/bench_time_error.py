"""Issue 5: error against wall time, per scene, for every way this project can make an image.

Methods: our brute-force path tracer at rising spp; Mitsuba 3's (llvm_ad_rgb when LLVM 19 is present,
else scalar_rgb; printed) at the same spp; 1 spp + our denoiser (the fused on-device pipeline); learned
adaptive sampling at rising mean-spp budgets + our denoiser; Intel OIDN (pyoidn, hdr=True, albedo and
normal guides) on our 1-spp render. Gold: our own render at --gold-spp with a different seed (kept in
--gold-cache when given, shared with bench_adaptive.py at the same size).

Prints every point (seconds, relMSE, FLIP, PSNR), then a table of the time each method needs to reach
the relMSE of 64-, 256- and 1024-spp brute force (log-log interpolation along a method's curve; a
single-point method reaches a target only if its one point is at or below it; '—' = never reached in
the measured range), and writes benchmarks/plots/time_error_<scene>.png.

    python3 benchmarks/bench_time_error.py [--quick] [--size 96x96] [--spp 1 4 16 64 256 1024]
        [--gold-spp 8192] [--gold-cache DIR] [--budgets 2 4 8 16] [--scenes cornell cornell-glossy sun-room bunny]
        [--models DIR | --seed-models] [--no-mitsuba]
"""

from __future__ import annotations

import argparse

import numpy as np
from common import (add_gold_arguments, add_model_arguments, crossing, errors, gold_render, hdr_pipeline, image_size,
                    linear_frame, load_scenes, mitsuba, oidn, parse_with_quick_defaults, print_header,
                    print_table, resolve_models, save_figure, steady)

from wgpu_rt.renderer import render
from wgpu_rt.scene.mitsuba import timed_render
from wgpu_rt.trace.trace_pass import AUX_SAMPLES

TARGET_SPP = (64, 256, 1024)
QUICK = {"size": "32x32", "spp": [1, 4, 16, 64, 256, 1024], "gold_spp": 2048, "budgets": [2, 4, 8]}


def parse_args():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["cornell", "cornell-glossy", "sun-room", "bunny"])
    parser.add_argument("--size", type=image_size, default="96x96")
    parser.add_argument("--spp", type=int, nargs="+", default=[1, 4, 16, 64, 256, 1024],
                        help="brute-force sample counts (ours and Mitsuba); include 64, 256 and 1024")
    parser.add_argument("--budgets", type=float, nargs="+", default=[2, 4, 8, 16],
                        help="mean spp budgets of adaptive + denoise")
    parser.add_argument("--max-depth", type=int, default=8)
    parser.add_argument("--no-mitsuba", action="store_true")
    add_gold_arguments(parser, default_spp=8192)
    add_model_arguments(parser)
    return parse_with_quick_defaults(parser, QUICK)


def measure(scene, size, args, mi) -> dict[str, list[dict]]:
    """Every method's points: {method: [{"x": parameter, "seconds": …, "relMSE": …, …}, …]}."""
    gold = gold_render(scene, size, args)
    points: dict[str, list[dict]] = {}

    def add(method, x, seconds, image):
        points.setdefault(method, []).append({"x": x, "seconds": seconds, **errors(gold, image)})

    for spp in sorted(args.spp):
        result = render(scene, spp=spp, size=size, max_depth=args.max_depth, seed=0, aovs=())
        add("ours brute force", spp, result.seconds, result.color)
    if mi is not None:
        timed_render(mi, scene, size, 1, args.max_depth)                        # JIT warm-up
        for spp in sorted(args.spp):
            image, seconds = timed_render(mi, scene, size, spp, args.max_depth)
            add(f"Mitsuba brute force ({mi.variant()})", spp, seconds, image)
    pipeline = hdr_pipeline(scene, size, args, denoise=True)
    image, seconds = steady(lambda: linear_frame(pipeline), repeats=3)
    add("1 spp + denoise", 1, seconds, image)
    for budget in sorted(args.budgets):
        pipeline = hdr_pipeline(scene, size, args, denoise=True, adaptive=budget)
        image, seconds = steady(lambda: linear_frame(pipeline), repeats=3)
        add("adaptive + denoise", budget, seconds, image)
    one = render(scene, spp=1, size=size, max_depth=args.max_depth, seed=0, aovs=("albedo", "normal"),
                 aux_samples=AUX_SAMPLES)   # the albedo ours gets, its aux pass timed with the render
    image, seconds = steady(lambda: oidn(one.color, one.aovs["albedo"], one.aovs["normal"]), repeats=3)
    add("1 spp + OIDN (CPU)", 1, one.seconds + seconds, image)
    return points


def plot(scene_name, size, points, targets) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [n for n in ("relMSE", "FLIP", "PSNR") if n in next(iter(points.values()))[0]]
    figure, axes = plt.subplots(1, len(names), figsize=(5.2 * len(names), 4.2))
    for axis, name in zip(np.atleast_1d(axes), names):
        for method, curve in points.items():
            axis.plot([p["seconds"] for p in curve], [p[name] for p in curve], "o-" if len(curve) > 1 else "s",
                      label=method)
        if name == "relMSE":
            for spp, target in targets.items():
                axis.axhline(target, color="grey", lw=0.7, ls="--")
                axis.annotate(f"{spp} spp", (0.99, target), xycoords=("axes fraction", "data"), ha="right",
                              va="bottom", fontsize=7, color="grey")
            axis.set_yscale("log")
        axis.set_xscale("log")
        axis.set_xlabel("wall time (s)")
        axis.set_ylabel(name + (" (dB, higher is better)" if name == "PSNR" else " (lower is better)"))
        axis.grid(True, which="both", alpha=0.3)
    handles, labels = np.atleast_1d(axes)[0].get_legend_handles_labels()
    figure.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8, bbox_to_anchor=(0.5, -0.06))
    figure.suptitle(f"{scene_name} {size[0]}×{size[1]}: error against time")
    path = save_figure(figure, f"time_error_{scene_name}.png")
    plt.close(figure)
    return str(path)


def main() -> None:
    args = parse_args()
    resolve_models(args)
    print_header(args)
    size = args.size
    mi = None
    if not args.no_mitsuba:
        mi, variant = mitsuba()
        print(f"mitsuba: {variant}" + (" (no LLVM 19: scalar, slow)" if variant == "scalar_rgb" else ""))
    print(f"size {size[0]}x{size[1]}, brute force spp {sorted(args.spp)}, gold {args.gold_spp} spp (ours, "
          f"seed 12345), adaptive budgets {sorted(args.budgets)}, max depth {args.max_depth}")
    for scene in load_scenes(args.scenes):
        points = measure(scene, size, args, mi)
        rows = [[method, p["x"], p["seconds"], *(p.get(k) for k in ("relMSE", "FLIP", "PSNR"))]
                for method, curve in points.items() for p in curve]
        print_table(f"{scene.name}: every point", ["method", "spp/budget", "seconds", "relMSE", "FLIP", "PSNR"],
                    rows)
        brute = points["ours brute force"]
        targets = {spp: next(p["relMSE"] for p in brute if p["x"] == spp) for spp in TARGET_SPP
                   if any(p["x"] == spp for p in brute)}
        table = []
        for method, curve in points.items():
            curve = sorted(curve, key=lambda p: p["seconds"])
            if len(curve) == 1:
                times = [curve[0]["seconds"] if curve[0]["relMSE"] <= t else None for t in targets.values()]
            else:
                times = [crossing([p["seconds"] for p in curve], [p["relMSE"] for p in curve], t)
                         for t in targets.values()]
            table.append([method, *times])
        print_table(f"{scene.name}: seconds to reach the relMSE of N-spp brute force (ours)",
                    ["method", *(f"{spp} spp ({t:.3g})" for spp, t in targets.items())], table)
        print(f"plot: {plot(scene.name, size, points, targets)}")


if __name__ == "__main__":
    main()
