"""Equal-error sample savings of learned adaptive sampling: the mean spp that uniform sampling needs to
reach the error adaptive sampling reaches at a budget B, divided by B (> 1: adaptive saves samples).

Samplers run through the fused pipeline's probe → sample map → targeted trace, each spending exactly
B·pixels samples (the measured mean spp and the share of pixels at the per-pixel cap are printed):
``heat`` (the Error Predictor, learned) and ``variance`` (Cycles' half-buffer error of a 2-spp probe,
the classic baseline). The reference curve is brute-force rendering at --uniform spp: the pipeline's
``uniform`` sampler at an integer budget B is exactly brute-force B spp (tests/test_adaptive.py), and
the curve reaches past the samplers' 32-spp ceiling. --k, --variance-k and --uniform-share sweep the
importance's power and the share of the budget spread evenly (AdaptiveSettings; default: its defaults).

Three errors, each the mean over --seeds of the raw (not denoised) radiance against our own
--gold-spp render (seed 12345): relMSE; trimmed relMSE (each pixel's relMSE clipped at the image's
99.9th percentile, so the few fireflies that dominate relMSE at low spp do not decide); and the
display-space MSE behind metrics.psnr (Reinhard + gamma, fireflies bounded). The uniform spp matching
an error comes from a least-squares power law, error = c·spp^−α, fitted to the whole uniform curve in
log-log (α is printed; 1 is plain Monte Carlo): with a few seeds the curve itself is noisy, and on
firefly-heavy scenes (cornell-glossy) not even monotone, so interpolating between neighbouring points
would hand the noise of one point to the savings. --denoised adds the relMSE of the denoised output. Plots: benchmarks/plots/adaptive_savings_<scene>.png.

    python3 benchmarks/bench_adaptive.py [--quick] [--size 96x96] [--budgets 2 4 8 16] [--seeds 3]
        [--k 1 3] [--variance-k 1] [--uniform-share 0 0.5] [--gold-spp 8192] [--gold-cache DIR] [--denoised]
        [--scenes cornell cornell-glossy sun-room bunny] [--models DIR | --seed-models]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from common import (add_gold_arguments, add_model_arguments, gold_render, hdr_pipeline, linear_frame,
                    load_scenes, parse_with_quick_defaults, print_header, print_table, resolve_models,
                    save_figure, trimmed_rel_mse)

from wgpu_rt import metrics
from wgpu_rt.frame.adaptive import EXTRA_SAMPLES, AdaptiveSettings
from wgpu_rt.render import parse_size, render

UNIFORM_SPP = [1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64]
QUICK = {"size": "32x32", "budgets": [2, 4, 8], "seeds": 1, "gold_spp": 2048, "uniform": [1, 2, 4, 8, 16, 32]}
RAW_METRICS = ("relMSE", "trimmed relMSE", "display MSE")


def parse_args():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["cornell", "cornell-glossy", "sun-room", "bunny"])
    parser.add_argument("--size", default="96x96")
    parser.add_argument("--budgets", type=float, nargs="+", default=[2, 4, 8, 16])
    parser.add_argument("--uniform", type=int, nargs="+", default=UNIFORM_SPP,
                        help="spp of the brute-force uniform reference curve")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--k", type=float, nargs="+", default=[None],
                        help="powers of the heat sampler's importance (default: AdaptiveSettings' default)")
    parser.add_argument("--variance-k", type=float, nargs="+", default=[None],
                        help="powers of the variance sampler's importance")
    parser.add_argument("--uniform-share", type=float, nargs="+", default=[None],
                        help="shares of the extra samples spread evenly (both samplers)")
    parser.add_argument("--denoised", action="store_true", help="also measure the denoised output's relMSE")
    parser.add_argument("--max-depth", type=int, default=8)
    add_gold_arguments(parser, default_spp=8192)
    add_model_arguments(parser)
    return parse_with_quick_defaults(parser, QUICK)


def raw_errors(gold, image) -> dict[str, float]:
    return {"relMSE": metrics.rel_mse(gold, image), "trimmed relMSE": trimmed_rel_mse(gold, image),
            "display MSE": float(np.mean((metrics.to_display(image) - metrics.to_display(gold)) ** 2))}


def uniform_curve(scene, size, args, gold) -> dict[int, dict[str, float]]:
    """{spp: mean errors over the seeds} of brute-force rendering."""
    curve = {}
    for spp in sorted(args.uniform):
        runs = [raw_errors(gold, render(scene, spp=spp, size=size, max_depth=args.max_depth, seed=seed,
                                        aovs=()).color) for seed in range(args.seeds)]
        curve[spp] = {name: float(np.mean([r[name] for r in runs])) for name in RAW_METRICS}
    return curve


def sampler_errors(scene, size, args, gold, settings: AdaptiveSettings) -> dict[str, float]:
    """Mean errors over the seeds of one sampler and budget, with the measured mean spp and the share of
    pixels at the per-pixel cap."""
    runs = []
    for seed in range(args.seeds):
        pipeline = hdr_pipeline(scene, size, args, denoise=args.denoised, seed=seed, adaptive=settings)
        output = linear_frame(pipeline, scene)
        run = raw_errors(gold, pipeline.buffers.read("radiance").transpose(1, 2, 0))
        if args.denoised:
            run["denoised relMSE"] = metrics.rel_mse(gold, output)
        run["mean spp"] = float(pipeline.buffers.read("spp").mean())
        run["capped"] = float(np.mean(pipeline.buffers.read(EXTRA_SAMPLES.name) >= settings.cap))
        runs.append(run)
    return {name: float(np.mean([r[name] for r in runs])) for name in runs[0]}


def power_law(curve, column: str) -> tuple[float, float]:
    """(log c, α) of the least-squares fit log error = log c − α·log spp along the uniform curve."""
    slope, intercept = np.polyfit(np.log(list(curve)), np.log([point[column] for point in curve.values()]), 1)
    return float(intercept), float(-slope)


def savings(fit: tuple[float, float], error: float, budget: float) -> float:
    """The uniform spp the fitted power law needs to reach ``error``, divided by ``budget``."""
    log_c, alpha = fit
    return float(np.exp((log_c - np.log(error)) / alpha)) / budget


def plot(scene_name, size, rows) -> str:
    """Savings against budget, one line per sampler setting, one panel per error."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, len(RAW_METRICS), figsize=(5 * len(RAW_METRICS), 4), sharey=True)
    settings = sorted({tuple(row[:3]) for row in rows}, key=str)
    for column, (axis, name) in enumerate(zip(axes, RAW_METRICS)):
        for index, (sampler, k, even) in enumerate(settings):
            points = [(row[3], row[7 + column]) for row in rows if tuple(row[:3]) == (sampler, k, even)]
            axis.plot(*zip(*points), "o-", color=f"C{index}", label=f"{sampler} k={k:g} even={even:g}")
        axis.axhline(1.0, color="grey", lw=0.8)
        axis.axhline(1.5, color="grey", lw=0.8, ls="--")
        axis.set_xscale("log", base=2)
        axis.set_xlabel("budget (mean spp)")
        axis.set_title(f"savings on {name}")
        axis.grid(True, alpha=0.3)
    axes[0].set_ylabel("uniform spp needed ÷ budget")
    axes[0].legend(fontsize=7)
    figure.suptitle(f"{scene_name} {size[0]}×{size[1]}: equal-error savings against uniform (dashed: 1.5×)")
    path = save_figure(figure, f"adaptive_savings_{scene_name}.png")
    plt.close(figure)
    return str(path)


def main() -> None:
    args = parse_args()
    resolve_models(args)
    print_header(args)
    size = parse_size(args.size)
    print(f"size {size[0]}x{size[1]}, budgets {args.budgets}, uniform curve {args.uniform}, {args.seeds} "
          f"seed(s), gold {args.gold_spp} spp, max depth {args.max_depth}")
    samplers = [(sampler, k, share) for sampler, ks in (("heat", args.k), ("variance", args.variance_k))
                for k in ks for share in args.uniform_share]
    started = time.perf_counter()
    summary = []
    for scene in load_scenes(args.scenes):
        gold = gold_render(scene, size, args)
        curve = uniform_curve(scene, size, args, gold)
        fits = {name: power_law(curve, name) for name in RAW_METRICS}
        print_table(f"{scene.name}: brute-force uniform reference curve", ["spp", *RAW_METRICS],
                    [[spp, *errors.values()] for spp, errors in curve.items()]
                    + [["fitted α", *(fits[name][1] for name in RAW_METRICS)]])
        rows = []
        for sampler, k, share in samplers:
            for budget in sorted(args.budgets):
                settings = AdaptiveSettings(sampler=sampler, budget=budget, k=k, uniform_share=share)
                measured = sampler_errors(scene, size, args, gold, settings)
                ratios = [savings(fits[name], measured[name], budget) for name in RAW_METRICS]
                rows.append([sampler, settings.exponent, settings.evenly_spread, budget,
                             measured["mean spp"], measured["capped"], measured["relMSE"], *ratios]
                            + ([measured["denoised relMSE"]] if args.denoised else []))
                summary.append([scene.name, *rows[-1][:4], *ratios])
        print_table(f"{scene.name}: equal-error savings (uniform spp needed ÷ budget; > 1 saves samples)",
                    ["sampler", "k", "even", "budget", "mean spp", "capped", "relMSE",
                     *(f"savings {n}" for n in RAW_METRICS)] + (["denoised relMSE"] if args.denoised else []),
                    rows)
        print(f"plot: {plot(scene.name, size, rows)}")
    print_table("all scenes: equal-error savings", ["scene", "sampler", "k", "even", "budget",
                                                     *(f"savings {n}" for n in RAW_METRICS)], summary)
    print(f"\nwall time {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
