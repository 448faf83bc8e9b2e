"""Denoiser, error predictor and confidence model on held-out views (the dataset's ``test`` split, whose
added objects are shapes no training view has).

Denoiser at 1 spp: PSNR / SSIM / FLIP / relMSE against gold, beside Intel OIDN (pyoidn, ``hdr=True``,
the same colour/albedo/normal) and brute force at rising spp; "equivalent spp" is the sample count at
which brute force reaches the denoiser's relMSE (log-log interpolation of the brute-force curve).
Error predictor: Spearman correlation of its heatmap with the true |1 spp − gold| log error. Confidence:
ROC AUC of 1 − its output (it predicts that history is valid) against the true disocclusion mask, with
the history reprojected as the runtime's temporal pass does: over all pixels ("model"), over the pixels
whose history passes the pass's depth/normal tests ("model, tested pixels": the only ones where the
model decides anything), and for the temporal stage as a whole ("temporal stage": failed tests count as
certain disocclusion, the model scores the rest). All networks run in the WGSL engine.

    python benchmarks/bench_denoise.py --data data/dataset [--models models] [--extra-spp 64 256] [--gold-spp 1024]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from wgpu_rt import metrics
from wgpu_rt.commands.denoise import denoise
from wgpu_rt.dataset import DatasetConfig, TruthEngine, load_views, plan_views, read_manifest
from wgpu_rt.frame.pack import pack_confidence_input, pack_error_input
from wgpu_rt.nn import WgslModel
from wgpu_rt.train.targets import confidence_pair, error_heatmap
from wgpu_rt.train.trainer import rank_correlation, roc_auc


def equivalent_spp(spp: list[int], error: list[float], target: float) -> str:
    """The sample count at which brute force's ``error`` (lower is better) first falls to ``target``,
    interpolated in log-log on the first segment that crosses it; "< 1" / "> N" outside the measured
    range (the curve is noisy at high spp when gold itself has few samples, so only crossings count)."""
    x, y = np.log(np.asarray(spp, float)), np.log(np.asarray(error, float))
    t = np.log(target)
    if t >= y[0]:
        return f"< {spp[0]}"
    for i in range(len(x) - 1):
        if y[i] >= t >= y[i + 1]:
            return f"{np.exp(x[i] + (t - y[i]) * (x[i + 1] - x[i]) / (y[i + 1] - y[i])):.1f}"
    return f"> {spp[-1]}"


def render_test_views(data: Path, view_ids: set[str], spp: list[int], seed: int) -> dict[str, dict[int, np.ndarray]]:
    """Renders of the test views' frame 0 at each of ``spp`` (the dataset's scenes, seeds ``seed`` + spp,
    independent of the dataset's own renders)."""
    from wgpu_rt.render import render

    config = read_manifest(data)["config"]
    config = DatasetConfig(**{**config, "scenes": tuple(config["scenes"]), "spp": tuple(config["spp"])})
    engine = TruthEngine(config, data, renderer=render)
    result = {}
    for plan in plan_views(config):
        if plan.view_id in view_ids:
            scene = engine.scene_for(plan)
            result[plan.view_id] = {s: render(scene, spp=s, size=(config.size, config.size),
                                              max_depth=config.max_depth, seed=seed + s, frame=0, aovs=()).color
                                    for s in spp}
    return result


def reference_gold(data: Path, view_ids: set[str], spp: int) -> dict[str, np.ndarray]:
    """A higher-spp gold for the test views, rendered once and kept under DATA/reference/ (so that the
    evaluation is not capped by the dataset gold's own noise)."""
    folder = data / "reference"
    paths = {v: folder / f"{v}_{spp}spp.npy" for v in view_ids}
    missing = {v for v, path in paths.items() if not path.exists()}
    if missing:
        folder.mkdir(exist_ok=True)
        for view_id, images in render_test_views(data, missing, [spp], seed=20_000).items():
            tmp = paths[view_id].with_suffix(".tmp.npy")
            np.save(tmp, np.asarray(images[spp], np.float32))
            os.replace(tmp, paths[view_id])
    return {v: np.load(path) for v, path in paths.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", required=True)
    parser.add_argument("--models", default="models")
    parser.add_argument("--split", default="test")
    parser.add_argument("--precision", default="fp32", choices=["fp32", "fp16"])
    parser.add_argument("--extra-spp", type=int, nargs="*", default=[64],
                        help="brute-force sample counts rendered now, beyond the dataset's")
    parser.add_argument("--gold-spp", type=int, default=None,
                        help="score against a gold rendered at this spp (cached in DATA/reference/) instead of "
                             "the dataset's; the dataset's gold then joins the brute-force rows")
    args = parser.parse_args()

    import pyoidn

    views = load_views(args.data, args.split)
    models = Path(args.models)
    denoiser = WgslModel(models / "denoiser.onnx", precision=args.precision)
    error_model = WgslModel(models / "error_predictor.onnx", precision=args.precision)
    confidence_model = WgslModel(models / "confidence.onnx", precision=args.precision)
    view_ids = {v.view_id for v in views}
    dataset_gold_spp = int(read_manifest(args.data)["config"]["gold"])
    extra = render_test_views(Path(args.data), view_ids, args.extra_spp, seed=10_000) if args.extra_spp else {}
    gold_override = reference_gold(Path(args.data), view_ids, args.gold_spp) if args.gold_spp else {}

    first = views[0].frames[0].noisy[1]   # warm-up: pipeline compilation is not denoising time
    denoise(denoiser, first["color"], first["albedo"], first["normal"], first["depth"])
    pyoidn.denoise(np.ascontiguousarray(first["color"]), hdr=True)

    rows: dict[str, list[dict]] = {}
    seconds = {"ours": 0.0, "oidn": 0.0}
    spearman, auc = [], {"model": [], "model, tested pixels": [], "temporal stage": []}
    for view in views:
        frame = view.frames[0]
        gold, noisy = gold_override.get(view.view_id, frame.gold["color"]), frame.noisy[1]
        started = time.perf_counter()
        ours = denoise(denoiser, noisy["color"], noisy["albedo"], noisy["normal"], noisy["depth"])
        seconds["ours"] += time.perf_counter() - started
        started = time.perf_counter()
        oidn = pyoidn.denoise(np.ascontiguousarray(noisy["color"]), np.ascontiguousarray(noisy["albedo"]),
                              np.ascontiguousarray(noisy["normal"]), hdr=True)
        seconds["oidn"] += time.perf_counter() - started
        candidates = {"ours (1 spp)": ours, "OIDN (1 spp)": oidn}
        for spp, render in sorted({**{s: frame.noisy[s]["color"] for s in view.spp},
                                   **extra.get(view.view_id, {})}.items()):
            candidates[f"brute {spp} spp"] = render
        if gold_override:
            candidates[f"dataset gold {dataset_gold_spp}"] = frame.gold["color"]
        for name, image in candidates.items():
            rows.setdefault(name, []).append(metrics.all_metrics(gold, image))

        heat = np.asarray(error_model(pack_error_input(noisy["color"])[None]))[0, 0]
        spearman.append(rank_correlation(heat, error_heatmap(noisy["color"], gold)))
        for previous, current in zip(view.frames, view.frames[1:]):
            history, history_depth, valid, mask = confidence_pair(previous, current)
            x = pack_confidence_input(current.noisy[1]["color"], history, current.noisy[1]["depth"], history_depth)
            invalid = 1.0 - np.asarray(confidence_model(x[None]))[0, 0]    # the model says "history valid"
            auc["model"].append(roc_auc(invalid, mask))
            auc["model, tested pixels"].append(roc_auc(invalid[valid], mask[valid]))
            auc["temporal stage"].append(roc_auc(np.where(valid, invalid, 1.0), mask))

    gold_spp = args.gold_spp or dataset_gold_spp
    print(f"{len(views)} held-out views ({args.split} split of {args.data}), "
          f"{views[0].frames[0].gold['color'].shape[1]}² px, precision {args.precision}, gold {gold_spp} spp")
    keys = list(rows["ours (1 spp)"][0])
    print(f"{'method':18s}" + "".join(f"{k:>10s}" for k in keys))
    means = {name: {k: float(np.mean([r[k] for r in values])) for k in keys} for name, values in rows.items()}
    for name, m in means.items():
        print(f"{name:18s}" + "".join(f"{m[k]:10.4f}" for k in keys))
    brute = sorted((int(n.split()[1]), m) for n, m in means.items() if n.startswith("brute"))
    display_mse = lambda m: 10 ** (-m["psnr"] / 10)  # noqa: E731  (the MSE behind the PSNR)
    for name in ("ours (1 spp)", "OIDN (1 spp)"):
        by_rel_mse = equivalent_spp([b for b, _ in brute], [m["rel_mse"] for _, m in brute], means[name]["rel_mse"])
        by_psnr = equivalent_spp([b for b, _ in brute], [display_mse(m) for _, m in brute], display_mse(means[name]))
        print(f"equivalent spp of {name}: {by_rel_mse} by relMSE, {by_psnr} by PSNR")
    print(f"time per view: ours {seconds['ours'] / len(views):.3f} s (WGSL on the adapter), "
          f"OIDN {seconds['oidn'] / len(views):.3f} s (CPU); ratio ours/OIDN "
          f"{seconds['ours'] / max(seconds['oidn'], 1e-9):.2f}")
    print(f"error predictor: Spearman vs true error {np.mean(spearman):.3f} (min {np.min(spearman):.3f})")
    if auc["model"]:
        print(f"confidence: ROC AUC vs true disocclusion mask over {len(auc['model'])} frame pairs: "
              + ", ".join(f"{name} {np.mean(values):.3f}" for name, values in auc.items()))


if __name__ == "__main__":
    main()
