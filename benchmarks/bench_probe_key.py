"""Equal-error savings of the heat sampler when the error predictor reads its 1-spp probe at one radiance key,
or at another scale of the light: what the exposure step would do for a predictor trained without it.

Per scene and seed the pipeline's probe (brute-force 1 spp with the run's seed) is rendered, multiplied by
2^stops, divided by its ``radiance_exposure`` to the key (``none``: read as it is), run through the error
predictor by onnxruntime and handed to the pipeline's allocation as a fixed importance (as bench_adaptive.py's
oracles are); the rest is bench_adaptive.py's: the targeted pass, the errors against the gold at the scene's own
scale, the savings against the fitted brute-force curve. A row ``none @ s`` is the predictor on the scene with
2^s times its light (which renders exactly scaled: ``Scene.with_light_scaled``); a row ``K @ 0`` is the
predictor reading every scale alike, at key K. The last table is the geometric mean over the scenes
(BENCHMARKS.md §41).

    python3 benchmarks/bench_probe_key.py --variants none@0 0.3@0 none@-8 none@8 --size 64x64 --budgets 2 4 8 \
        --seeds 3 --gold-spp 8192 --gold-cache /tmp/gold64 --scenes cornell sun-room world-2147483654
"""

from __future__ import annotations

import argparse
import functools
import sys

import numpy as np
from bench_adaptive import (RAW_METRICS, FixedImportance, geometric_means, power_law, sampler_errors, savings,
                            uniform_curve)
from common import (add_gold_arguments, add_model_arguments, gold_render, image_size, load_scenes,
                    parse_with_quick_defaults, print_header, print_table, resolve_models)

from wgpu_rt.frame.adaptive import AdaptiveSettings
from wgpu_rt.frame.pack import pack_error_input, radiance_exposure
from wgpu_rt.renderer import render


def variant(text: str) -> tuple[float | None, float]:
    """``KEY@STOPS`` (KEY a radiance key or ``none``) → (key or None, stops)."""
    try:
        key, stops = text.split("@")
        return (None if key == "none" else float(key)), float(stops)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not KEY@STOPS (KEY a number or none)") from None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["cornell", "cornell-glossy", "sun-room"])
    parser.add_argument("--variants", type=variant, nargs="+", default=[variant("none@0"), variant("0.3@0")],
                        metavar="KEY@STOPS")
    parser.add_argument("--size", type=image_size, default="64x64")
    parser.add_argument("--budgets", type=float, nargs="+", default=[2, 4, 8])
    parser.add_argument("--uniform", type=int, nargs="+", default=[1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--max-depth", type=int, default=8)
    add_gold_arguments(parser, default_spp=8192)
    add_model_arguments(parser)
    args = parse_with_quick_defaults(parser, {"size": "32x32", "budgets": [2, 4], "seeds": 1, "gold_spp": 1024,
                                              "uniform": [1, 2, 4, 8, 16, 32]})
    args.denoised = False   # sampler_errors' raw errors only
    resolve_models(args)
    print_header(args)
    import onnxruntime

    from wgpu_rt.models import ERROR_PREDICTOR

    session = onnxruntime.InferenceSession(str(ERROR_PREDICTOR.path(args.models)), providers=["CPUExecutionProvider"])
    name = session.get_inputs()[0].name

    def importance(scene, key, stops):
        @functools.cache   # one probe and heat a seed, shared by the budgets
        def model(seed):
            probe = render(scene, spp=1, size=args.size, max_depth=args.max_depth, seed=seed, aovs=()).color
            probe = probe * np.float32(2.0 ** stops)
            exposure = 1.0 if key is None else radiance_exposure(probe, key)
            return FixedImportance(session.run(None, {name: pack_error_input(probe, exposure)[None]})[0][0, 0])
        return model

    labels = [f"{'none' if key is None else f'{key:g}'} @ {stops:+g}" for key, stops in args.variants]
    summary = []
    for scene in load_scenes(args.scenes):
        gold = gold_render(scene, args.size, args)
        fits = {metric: power_law(uniform_curve(scene, args.size, args, gold), metric) for metric in RAW_METRICS}
        probe = render(scene, spp=1, size=args.size, max_depth=args.max_depth, seed=0, aovs=()).color
        rows = []
        for label, (key, stops) in zip(labels, args.variants):
            model = importance(scene, key, stops)
            for budget in args.budgets:
                measured = sampler_errors(scene, args.size, args, gold, AdaptiveSettings(sampler="heat", budget=budget),
                                          model)
                rows.append([label, budget, *(savings(fits[m], measured[m], budget) for m in RAW_METRICS)])
                summary.append([scene.name, label, 0, 0, 0, budget, *rows[-1][2:]])
        print_table(f"{scene.name} (radiance key {radiance_exposure(probe, 1.0):.4g}): savings",
                    ["key @ stops", "budget", *(f"savings {m}" for m in RAW_METRICS)], rows)
        sys.stdout.flush()
    means = geometric_means(summary)
    print_table("geometric mean over the scenes", ["key @ stops", "budget", *(f"savings {m}" for m in RAW_METRICS)],
                [[row[0], row[4], *row[5:]] for row in means])


if __name__ == "__main__":
    main()
