"""Equal-error sample savings of learned adaptive sampling: the mean spp that uniform sampling needs to
reach the error adaptive sampling reaches at a budget B, divided by B (> 1: adaptive saves samples).

Samplers (all through the fused pipeline's targeted trace, so each spends exactly B·pixels samples):
``heat`` (the Error Predictor, learned), ``variance`` (Cycles' half-buffer error of a 2-spp probe, the
classic baseline) and ``uniform`` (the same budget spread evenly: the reference curve). Error is relMSE
against our own high-spp gold, of the raw radiance and of the denoised output, averaged over --seeds;
the uniform spp matching an error is interpolated log-log along the uniform curve ('—' if outside it).

    python3 benchmarks/bench_adaptive.py [--quick] [--size 96x96] [--budgets 2 4 8 16] [--seeds 3]
        [--scenes cornell cornell-glossy sun-room bunny] [--models DIR | --seed-models]
"""

from __future__ import annotations

import argparse

import numpy as np
from common import (add_model_arguments, crossing, hdr_pipeline, linear_frame, load_scenes,
                    parse_with_quick_defaults, print_header, print_table, resolve_models)

from wgpu_rt import metrics
from wgpu_rt.frame.adaptive import AdaptiveSettings
from wgpu_rt.render import parse_size, render

UNIFORM_BUDGETS = [1, 2, 3, 4, 6, 8, 12, 16, 24, 32]
QUICK = {"size": "32x32", "budgets": [2, 4, 8], "seeds": 1, "gold_spp": 2048, "uniform": [1, 2, 4, 8, 16, 32]}


def parse_args():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["cornell", "cornell-glossy", "sun-room", "bunny"])
    parser.add_argument("--size", default="96x96")
    parser.add_argument("--budgets", type=float, nargs="+", default=[2, 4, 8, 16])
    parser.add_argument("--uniform", type=float, nargs="+", default=UNIFORM_BUDGETS,
                        help="budgets of the uniform reference curve (1 … 32)")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--gold-spp", type=int, default=16384)
    parser.add_argument("--max-depth", type=int, default=8)
    add_model_arguments(parser)
    return parse_with_quick_defaults(parser, QUICK)


def mean_errors(scene, size, args, gold, sampler: str, budget: float) -> tuple[float, float]:
    """(raw relMSE, denoised relMSE) of ``sampler`` at ``budget``, averaged over the seeds."""
    raw, denoised = [], []
    for seed in range(args.seeds):
        pipeline = hdr_pipeline(scene, size, args, denoise=True, seed=seed,
                                adaptive=AdaptiveSettings(sampler=sampler, budget=budget))
        denoised.append(metrics.rel_mse(gold, linear_frame(pipeline, scene)))
        raw.append(metrics.rel_mse(gold, pipeline.buffers.read("radiance").transpose(1, 2, 0)))
    return float(np.mean(raw)), float(np.mean(denoised))


def main() -> None:
    args = parse_args()
    resolve_models(args)
    print_header(args)
    size = parse_size(args.size)
    print(f"size {size[0]}x{size[1]}, budgets {args.budgets}, uniform curve {args.uniform}, {args.seeds} "
          f"seed(s), gold {args.gold_spp} spp, max depth {args.max_depth}")
    for scene in load_scenes(args.scenes):
        gold = render(scene, spp=args.gold_spp, size=size, max_depth=args.max_depth, seed=12345, aovs=()).color
        uniform = {b: mean_errors(scene, size, args, gold, "uniform", b) for b in sorted(args.uniform)}
        print_table(f"{scene.name}: uniform reference curve", ["mean spp", "relMSE raw", "relMSE denoised"],
                    [[b, *e] for b, e in uniform.items()])
        rows = []
        for sampler in ("heat", "variance"):
            for budget in sorted(args.budgets):
                raw, denoised = mean_errors(scene, size, args, gold, sampler, budget)
                ratios = []
                for column, error in enumerate((raw, denoised)):
                    spp = crossing(list(uniform), [e[column] for e in uniform.values()], error)
                    ratios.append(None if spp is None else spp / budget)
                rows.append([sampler, budget, raw, ratios[0], denoised, ratios[1]])
        print_table(f"{scene.name}: equal-error savings (uniform spp needed ÷ budget; > 1 saves samples)",
                    ["sampler", "budget", "relMSE raw", "savings raw", "relMSE denoised", "savings denoised"], rows)


if __name__ == "__main__":
    main()
