"""Equal-error sample savings of learned adaptive sampling: the mean spp that uniform sampling needs to
reach the error adaptive sampling reaches at a budget B, divided by B (> 1: adaptive saves samples).

Samplers run through the fused pipeline's probe → sample map → targeted trace, each spending exactly
B·pixels samples (the measured mean spp and the share of pixels at the per-pixel cap are printed):
``heat`` (the Error Predictor, learned) and ``variance`` (Cycles' half-buffer error of a 2-spp probe,
the classic baseline). --oracle adds three allocations fed true errors in place of the heatmap (k 1, no
pooling, nothing spread evenly): ``oracle σ``, the per-sample error sqrt(mean_c σ_c² / (μ_c² + ε)) (σ²
from --oracle-renders independent 1-spp renders against the gold, μ the gold; the allocation relMSE
asks for in expectation, n ∝ σ/sqrt(μ² + ε)), and ``oracle probe``, which also knows each run's own
probe error δ: sqrt(mean_c δ_c² / (μ_c² + ε) + σ-term²) (relMSE after n samples is (δ² + (n − 1)σ²)/n²
per pixel, so the probe's own error decides at low budgets). The first bounds a predictor of σ, the
second a perfect predictor of what the heat is trained on (one probe's error); the third, ``oracle
denoised``, knows where each run's denoised probe is wrong, sqrt(mean_c (d_c − μ_c)² / (μ_c² + ε)) with d
our denoiser's output on the probe: the bound for a predictor trained on the denoised frame's error.
--stops adds rows of the heat sampler on the scene with 2^stops times its light (``Scene.with_light_scaled``:
the same scene in other units, which renders exactly scaled), scored against the gold after dividing back:
an error predictor that reads its probe at one key (its ONNX file says so) gives the 0-stop row at any scale.
The reference curve is brute-force rendering at --uniform spp: the pipeline's
``uniform`` sampler at an integer budget B is exactly brute-force B spp (tests/test_adaptive.py), and
the curve reaches past the samplers' 32-spp ceiling. --k, --variance-k and --uniform-share sweep the
importance's power and the share of the budget spread evenly, --pool-sigma the heat's neighbourhood
pooling (AdaptiveSettings; default: its defaults). The last table is the geometric mean over the scenes.

Three errors, each the mean over --seeds of the raw (not denoised) radiance against our own
--gold-spp render (seed 12345): relMSE; trimmed relMSE (each pixel's relMSE clipped at the image's
99.9th percentile, so the few fireflies that dominate relMSE at low spp do not decide); and the
display-space MSE behind metrics.psnr (Reinhard + gamma, fireflies bounded). The uniform spp matching
an error comes from a least-squares power law, error = c·spp^−α, fitted to the whole uniform curve in
log-log (α is printed; 1 is plain Monte Carlo): with a few seeds the curve itself is noisy, and on
firefly-heavy scenes (cornell-glossy) not even monotone, so interpolating between neighbouring points
would hand the noise of one point to the savings. --denoised also denoises every frame (our denoiser)
and prints a second uniform curve, the pipeline's uniform sampler (brute force, tested) at the
--uniform spp up to its 32-spp ceiling, denoised the same way, and per sampler the denoised error
ratio: uniform's denoised relMSE at the budget ÷ the sampler's (> 1: adaptive helps after denoising).
Not equal-error savings: the denoised error hardly falls with spp (on cornell it is flat from 1 to 32
spp), so the spp uniform would need to match it is undefined.
Plots: benchmarks/plots/adaptive_savings_<scene>.png.

--pass-cost measures only the targeted pass's cost instead: per scene, sampler and budget, the device
time (timestamp queries) of the targeted pass on that sampler's own sample map, after the 1-spp probe
(and of its work list's build alone, the part before its batches), against a uniform pass of the same
total samples (budget − probe spp; whole budgets), --repeats pairs timed in alternation, printed as the
median of their ratios (1: the targeted pass costs what its samples cost). On a CPU adapter the ratio of
this process's CPU time is printed too: the cores are shared, and timestamps count the time other
programs took them.

    python3 benchmarks/bench_adaptive.py --pass-cost [--size 128x128] [--budgets 4] [--repeats 5]
        [--batch-items N ...] [--item-samples N ...]
    python3 benchmarks/bench_adaptive.py [--quick] [--size 96x96] [--budgets 2 4 8 16] [--seeds 3]
        [--k 1 3] [--variance-k 1] [--uniform-share 0 0.5] [--pool-sigma 0 2] [--oracle [--oracle-renders 64]]
        [--gold-spp 8192] [--gold-cache DIR] [--denoised] [--stops -8 8]
        [--scenes cornell cornell-glossy sun-room bunny] [--models DIR | --seed-models]
"""

from __future__ import annotations

import argparse
import itertools
import time
from pathlib import Path

import numpy as np
from common import (add_gold_arguments, add_model_arguments, denoiser_options, device_ms, gold_render, hdr_pipeline,
                    image_size, linear_frame, load_scenes, parse_with_quick_defaults, print_header, print_table,
                    resolve_models, save_array, save_figure, trimmed_rel_mse)

from wgpu_rt import metrics
from wgpu_rt.frame.adaptive import EXTRA_SAMPLES, MAX_HEAT_SAMPLES, AdaptiveSettings
from wgpu_rt.renderer import render

UNIFORM_SPP = [1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64]
QUICK = {"size": "32x32", "budgets": [2, 4, 8], "seeds": 1, "gold_spp": 2048, "uniform": [1, 2, 4, 8, 16, 32]}
RAW_METRICS = ("relMSE", "trimmed relMSE", "display MSE")
DENOISED = "denoised relMSE"
DENOISED_RATIO = "denoised error ratio"
ORACLES = ("oracle σ", "oracle probe", "oracle denoised")
ORACLE_SEED = 1000   # the oracle's 1-spp renders use seeds ORACLE_SEED..; the runs measured use 0..seeds-1


def parse_args():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["cornell", "cornell-glossy", "sun-room", "bunny"])
    parser.add_argument("--size", type=image_size, default="96x96")
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
    parser.add_argument("--pool-sigma", type=float, nargs="+", default=[None],
                        help="standard deviations (px) of the heat sampler's neighbourhood pooling (0: none)")
    parser.add_argument("--oracle", action="store_true",
                        help="also run the allocation on the true per-sample error (the importance's ceiling)")
    parser.add_argument("--oracle-renders", type=int, default=64,
                        help="independent 1-spp renders behind the oracle's per-pixel variance")
    parser.add_argument("--denoised", action="store_true", help="also measure the denoised output's relMSE")
    parser.add_argument("--stops", type=float, nargs="*", default=[],
                        help="also run the heat sampler on the scene with 2^stops times its light (its units "
                             "changed), scored after dividing back: one row each")
    parser.add_argument("--max-depth", type=int, default=8)
    parser.add_argument("--pass-cost", action="store_true",
                        help="only time the targeted pass against a uniform pass of the same samples")
    parser.add_argument("--repeats", type=int, default=5, help="timed pairs of passes with --pass-cost")
    parser.add_argument("--batch-items", type=int, nargs="+", default=[0], metavar="N",
                        help="with --pass-cost: work items per batch of the targeted pass, one set of rows each "
                             "(0, the default: the tracer's, about one uniform dispatch's samples)")
    parser.add_argument("--item-samples", type=int, nargs="+", default=[0], metavar="N",
                        help="with --pass-cost: the most samples a work item holds, one set of rows each (0, the "
                             "default: the tracer's; 1: a pixel's samples on neighbouring invocations, each its "
                             "own item, instead of one invocation's loop)")
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


class FixedImportance:
    """An error-predictor stand-in that hands the sample allocation a fixed (H, W) importance map."""

    def __init__(self, importance: np.ndarray):
        from wgpu_rt.gpu import get_context

        self.output = get_context().upload(np.ascontiguousarray(importance, np.float32))

    def record(self, encoder, input_buffer, height, width):
        return self.output


def oracle_importance(scene, size, args, gold) -> np.ndarray:
    """(H, W) sqrt(mean over channels of σ² / (μ² + ε)): σ² the mean squared error against the gold of
    --oracle-renders 1-spp renders (seeds ORACLE_SEED…, independent of the measured runs), μ the gold.
    Kept in --gold-cache beside the gold when given."""
    def compute():
        squared = np.zeros(gold.shape, np.float64)
        for index in range(args.oracle_renders):
            image = render(scene, spp=1, size=size, max_depth=args.max_depth, seed=ORACLE_SEED + index,
                           aovs=()).color
            squared += (np.nan_to_num(image.astype(np.float64)) - gold) ** 2
        variance = squared / args.oracle_renders
        return np.sqrt(np.mean(variance / (gold.astype(np.float64) ** 2 + metrics.REL_MSE_EPSILON), axis=-1))

    if not args.gold_cache:
        return compute()
    path = Path(args.gold_cache) / (f"{scene.name}_{size[0]}x{size[1]}_oracle{args.oracle_renders}"
                                    f"_gold{args.gold_spp}_depth{args.max_depth}.npy")
    if path.exists():
        return np.load(path)
    importance = compute()
    save_array(path, importance)
    return importance


def denoised_curve(scene, size, args, gold) -> dict[int, dict[str, float]]:
    """{spp: mean errors over the seeds} of uniform sampling through the pipeline, denoised, at the
    --uniform spp the uniform sampler reaches (1 + its 31-sample cap)."""
    return {spp: sampler_errors(scene, size, args, gold, AdaptiveSettings(sampler="uniform", budget=spp))
            for spp in sorted(args.uniform) if spp <= 1 + MAX_HEAT_SAMPLES}


def relative_squared_error(image: np.ndarray, gold: np.ndarray) -> np.ndarray:
    """(H, W) mean over channels of (x_c − μ_c)² / (μ_c² + ε): relMSE's per-pixel term."""
    delta = (np.nan_to_num(image.astype(np.float64)) - gold) ** 2
    return np.mean(delta / (gold.astype(np.float64) ** 2 + metrics.REL_MSE_EPSILON), axis=-1)


def probe_oracle(scene, size, args, gold, sigma_term: np.ndarray):
    """seed → FixedImportance of sqrt(mean_c δ_c² / (μ_c² + ε) + sigma_term²), δ that seed's probe error
    against the gold (the pipeline's probe is brute-force 1 spp with the run's seed, tested)."""
    def model(seed):
        probe = render(scene, spp=1, size=size, max_depth=args.max_depth, seed=seed, aovs=()).color
        return FixedImportance(np.sqrt(relative_squared_error(probe, gold) + sigma_term.astype(np.float64) ** 2))

    return model


def denoised_oracle(scene, size, args, gold):
    """seed → FixedImportance of sqrt(mean_c (d_c − μ_c)² / (μ_c² + ε)), d that seed's probe denoised by
    our denoiser: a perfect predictor of where the denoised 1-spp frame is wrong (what the samples must
    fix once the frame is denoised)."""
    def model(seed):
        denoised = render(scene, spp=1, size=size, max_depth=args.max_depth, seed=seed, aovs=(), denoise=True,
                          models_dir=args.models, precision=args.precision, **denoiser_options(args)).color
        return FixedImportance(np.sqrt(relative_squared_error(denoised, gold)))

    return model


def sampler_errors(scene, size, args, gold, settings: AdaptiveSettings, error_model=None,
                   stops: float = 0.0) -> dict[str, float]:
    """Mean errors over the seeds of one sampler and budget, with the measured mean spp and the share of
    pixels at the per-pixel cap. ``error_model``: a stand-in for the error predictor, or a function of
    the seed giving one. ``stops``: the scene rendered with 2^stops times its light
    (``Scene.with_light_scaled``; it renders exactly scaled), the images divided back before scoring."""
    runs, scale = [], np.float32(2.0 ** stops)
    lit = scene.with_light_scaled(scale) if stops else scene
    for seed in range(args.seeds):
        predictor = error_model(seed) if callable(error_model) else error_model
        renderer = hdr_pipeline(lit, size, args, denoise=args.denoised, seed=seed, adaptive=settings,
                                networks={"error_predictor": predictor} if predictor is not None else None)
        output = linear_frame(renderer) / scale
        buffers = renderer.pipeline.buffers   # the traced planes under the denoised output
        run = raw_errors(gold, buffers.read("radiance").transpose(1, 2, 0) / scale)
        if args.denoised:
            run[DENOISED] = metrics.rel_mse(gold, output)
        run["mean spp"] = float(buffers.read("spp").mean())
        run["capped"] = float(np.mean(buffers.read(EXTRA_SAMPLES.name) >= settings.cap))
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
    settings = sorted({tuple(row[:4]) for row in rows}, key=str)
    for column, (axis, name) in enumerate(zip(axes, RAW_METRICS)):
        for index, setting in enumerate(settings):
            points = [(row[4], row[8 + column]) for row in rows if tuple(row[:4]) == setting]
            sampler, k, even, pool = setting
            axis.plot(*zip(*points), "o-", color=f"C{index}",
                      label=f"{sampler} k={k:g} even={even:g} pool={pool:g}")
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


def geometric_means(summary) -> list[list]:
    """Per sampler setting and budget, the geometric mean of each ratio column over the scenes (None
    where a scene has none)."""
    groups: dict[tuple, list] = {}
    for row in summary:
        groups.setdefault(tuple(row[1:6]), []).append(row[6:])
    means = []
    for key, ratios in groups.items():
        columns = np.asarray([[np.nan if r is None else r for r in row] for row in ratios], float)
        mean = np.exp(np.mean(np.log(columns), axis=0))
        means.append([*key, *(None if np.isnan(m) else float(m) for m in mean)])
    return means


def base_sampler(label: str) -> str:
    """The AdaptiveSettings sampler a row's label runs: the oracles and the scaled-light rows are heat's."""
    return "heat" if label in ORACLES or label.startswith("heat at ") else label


def stops_of(label: str) -> float:
    """The stops of light a row's label runs the scene at ("heat at -4 stops"; 0 for the others)."""
    return float(label.split()[2]) if label.startswith("heat at ") else 0.0


def distinct_settings(samplers: list[tuple]) -> list[tuple]:
    """``samplers`` without the ones that resolve to the same settings as an earlier one (a sweep
    value equal to the default, or one that does not apply to that sampler)."""
    seen, kept = set(), []
    for sampler, k, share, pool in samplers:
        settings = AdaptiveSettings(sampler=base_sampler(sampler), budget=2.0, k=k, uniform_share=share,
                                    pool_sigma=pool)
        key = (sampler, settings.exponent, settings.evenly_spread, settings.pooling)
        if key not in seen:
            seen.add(key)
            kept.append((sampler, k, share, pool))
    return kept


def timed_pass(trace, buffers, timer, schedule) -> tuple[float, float]:
    """(device ms from timestamp queries, this process's CPU ms) of one pass adding ``schedule``'s
    samples after a 1-spp probe into cleared planes (the probe runs and is waited for first)."""
    from wgpu_rt.passes import SPP
    from wgpu_rt.trace.trace_pass import SampleSchedule

    ctx = trace.ctx
    encoder = ctx.device.create_command_encoder()
    trace.clear(encoder, buffers)
    trace.execute(encoder, buffers, SampleSchedule(samples=1))
    ctx.device.queue.submit([encoder.finish()])
    ctx.read(buffers.get(SPP), np.uint32, nbytes=4)
    encoder = ctx.device.create_command_encoder()
    timer.start()
    timer.mark(encoder, "start")
    trace.execute(encoder, buffers, schedule)
    timer.mark(encoder, "pass")
    encoder.resolve_query_set(timer.query_set, 0, 2, timer.resolved, 0)
    cpu = time.process_time()
    ctx.device.queue.submit([encoder.finish()])
    raw = ctx.device.queue.read_buffer(timer.resolved, 0, 16)
    return timer.stage_ms(timer.names, raw)["pass"], (time.process_time() - cpu) * 1e3


def timed_list_build(trace, buffers, timer, schedule) -> float:
    """Device ms of building the targeted pass's work list alone (the part of the pass before its batches)."""
    from wgpu_rt.passes import SPP

    work = trace.work_list
    return device_ms(trace.ctx, timer, lambda encoder: work.record_build(
        encoder, schedule.sample_counts, buffers.get(SPP), work.batches(schedule.samples, schedule.total_samples)))


def pass_cost_row(trace, counts, settings: AdaptiveSettings, extra: int, repeats: int) -> list[float]:
    """Median device ms of the targeted pass, of its work list's build alone and of a uniform pass of
    ``extra`` spp, timed in alternation, the median of the passes' pairwise ratios, and that ratio in
    process CPU time (what a CPU adapter spends, whatever else shares its cores; None on a GPU)."""
    from wgpu_rt.frame.pipeline import StageTimer
    from wgpu_rt.passes import FrameBuffers
    from wgpu_rt.trace.trace_pass import SampleSchedule

    buffers, timer = FrameBuffers(trace.ctx, trace.width, trace.height), StageTimer(trace.ctx, capacity=2)
    targeted = SampleSchedule(samples=settings.max_extra, sample_counts=counts,
                              total_samples=settings.extra_bound(trace.width * trace.height))
    uniform = SampleSchedule(samples=extra)
    timed_pass(trace, buffers, timer, targeted)   # compiles the kernels
    pairs = np.array([[timed_pass(trace, buffers, timer, schedule) for schedule in (targeted, uniform)]
                      for _ in range(repeats)])   # (repeat, targeted/uniform, device/cpu)
    ratios = pairs[:, 0] / pairs[:, 1]
    build = np.median([timed_list_build(trace, buffers, timer, targeted) for _ in range(repeats)])
    on_cpu = trace.ctx.adapter.info.get("adapter_type") == "CPU"
    return [float(np.median(pairs[:, 0, 0])), float(build), float(np.median(pairs[:, 1, 0])),
            float(np.median(ratios[:, 0])), float(np.median(ratios[:, 1])) if on_cpu else None]


def pass_cost(args, size) -> None:
    """The targeted pass's cost on each sampler's own sample map against a uniform pass of the same
    total samples: ratio 1 means the pass costs what its samples cost. The uniform sampler's map is
    the uniform pass's own samples, so its row is the targeted machinery's overhead alone; the others
    also carry the cost of the pixels they pick (noisy pixels may have longer paths)."""
    from wgpu_rt.accel.geometry import GeometryBuffers
    from wgpu_rt.gpu import get_context
    from wgpu_rt.trace.trace_pass import TracePass

    if not get_context().has_timestamps:
        raise SystemExit("--pass-cost needs timestamp queries, which this adapter lacks")
    rows = []
    for scene, batch_items, item_samples in itertools.product(load_scenes(args.scenes), args.batch_items,
                                                              args.item_samples):
        trace = TracePass(get_context(), scene, GeometryBuffers.build(scene), *size, max_depth=args.max_depth,
                          batch_items=batch_items or None, item_samples=item_samples or None)
        for sampler in ("heat", "variance", "uniform"):
            for budget in sorted(args.budgets):
                settings = AdaptiveSettings(sampler=sampler, budget=budget)
                extra = budget - settings.probe_samples
                if extra != int(extra) or extra < 1:
                    print(f"skipping {sampler} at budget {budget}: {extra:g} extra spp is no uniform pass")
                    continue
                renderer = hdr_pipeline(scene, size, args, seed=0, adaptive=settings)
                linear_frame(renderer)
                plane = renderer.pipeline.buffers.read(EXTRA_SAMPLES.name)
                rows.append([scene.name, sampler, budget, trace.batch_items, trace.item_samples,
                             float(plane.mean()), int(plane.max()),
                             float(np.mean(plane == 0)),
                             *pass_cost_row(trace, renderer.pipeline.buffers.get(EXTRA_SAMPLES), settings,
                                            int(extra), args.repeats)])
    print_table(f"targeted pass against a uniform pass of the same samples ({args.repeats} pairs timed in "
                f"alternation: device ms by timestamps, medians; ratio: median of the pairs' ratios)",
                ["scene", "sampler", "budget", "batch items", "item samples", "mean extra", "max extra",
                 "share with none",
                 "targeted ms", "list build ms", "uniform ms", "ratio", "CPU-time ratio"], rows)


def main() -> None:
    args = parse_args()
    resolve_models(args)
    print_header(args)
    size = args.size
    if args.pass_cost:
        pass_cost(args, size)
        return
    print(f"size {size[0]}x{size[1]}, budgets {args.budgets}, uniform curve {args.uniform}, {args.seeds} "
          f"seed(s), gold {args.gold_spp} spp, max depth {args.max_depth}")
    samplers = [("heat", k, share, pool) for k in args.k for share in args.uniform_share for pool in args.pool_sigma]
    samplers += [(f"heat at {stops:+g} stops", k, share, pool) for stops in args.stops
                 for k, share, pool in itertools.product(args.k, args.uniform_share, args.pool_sigma)]
    samplers += [("variance", k, share, None) for k in args.variance_k for share in args.uniform_share]
    if args.oracle:
        samplers += [(oracle, 1.0, 0.0, 0.0) for oracle in ORACLES]
    samplers = distinct_settings(samplers)
    started = time.perf_counter()
    summary = []
    for scene in load_scenes(args.scenes):
        gold = gold_render(scene, size, args)
        curve = uniform_curve(scene, size, args, gold)
        fits = {name: power_law(curve, name) for name in RAW_METRICS}
        print_table(f"{scene.name}: brute-force uniform reference curve", ["spp", *RAW_METRICS],
                    [[spp, *errors.values()] for spp, errors in curve.items()]
                    + [["fitted α", *(fits[name][1] for name in RAW_METRICS)]])
        if args.denoised:
            denoised = denoised_curve(scene, size, args, gold)
            print_table(f"{scene.name}: uniform reference curve, denoised", ["spp", DENOISED],
                        [[spp, errors[DENOISED]] for spp, errors in denoised.items()])
        oracles = {}
        if args.oracle:
            sigma_term = oracle_importance(scene, size, args, gold)
            oracles = {ORACLES[0]: FixedImportance(sigma_term),
                       ORACLES[1]: probe_oracle(scene, size, args, gold, sigma_term),
                       ORACLES[2]: denoised_oracle(scene, size, args, gold)}
        rows = []
        for sampler, k, share, pool in samplers:
            for budget in sorted(args.budgets):
                settings = AdaptiveSettings(sampler=base_sampler(sampler), budget=budget,
                                            k=k, uniform_share=share, pool_sigma=pool)
                measured = sampler_errors(scene, size, args, gold, settings,
                                          oracles.get(sampler), stops_of(sampler))
                ratios = [savings(fits[name], measured[name], budget) for name in RAW_METRICS]
                if args.denoised:
                    uniform_denoised = denoised.get(int(budget)) if budget == int(budget) else None
                    ratios.append(uniform_denoised[DENOISED] / measured[DENOISED] if uniform_denoised else None)
                rows.append([sampler, settings.exponent, settings.evenly_spread, settings.pooling, budget,
                             measured["mean spp"], measured["capped"], measured["relMSE"], *ratios]
                            + ([measured[DENOISED]] if args.denoised else []))
                summary.append([scene.name, *rows[-1][:5], *ratios])
        print_table(f"{scene.name}: equal-error savings (uniform spp needed ÷ budget; > 1 saves samples)",
                    ["sampler", "k", "even", "pool", "budget", "mean spp", "capped", "relMSE",
                     *(f"savings {n}" for n in RAW_METRICS)] + ([DENOISED_RATIO, DENOISED] if args.denoised else []),
                    rows)
        print(f"plot: {plot(scene.name, size, rows)}")
    headers = ["sampler", "k", "even", "pool", "budget", *(f"savings {n}" for n in RAW_METRICS)]
    headers += [DENOISED_RATIO] if args.denoised else []
    print_table("all scenes: equal-error savings", ["scene", *headers], summary)
    print_table("geometric mean over the scenes", headers, geometric_means(summary))
    print(f"\nwall time {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
