"""Denoiser, error predictor and confidence model on held-out views (the dataset's ``test`` split, whose
added objects are shapes no training view has).

Denoiser at 1 spp: PSNR / SSIM / FLIP / relMSE against gold, beside Intel OIDN (pyoidn, ``hdr=True``,
the same colour/albedo/normal, at each ``--oidn-quality``: balanced and high by default; on CUDA when
benchmarks/peers.py finds it, else on the CPU) and brute force at rising spp; "equivalent spp" is the
sample count at which brute force reaches the denoiser's relMSE (log-log interpolation of the
brute-force curve). Time per view is numpy in, numpy out on both sides (uploads and readbacks included).
Error predictor: Spearman correlation of its heatmap with the true |1 spp − gold| log error. Confidence:
ROC AUC of 1 − its output (it predicts that history is valid) against the true disocclusion mask, fed
what the temporal pass packs (the current frame denoised by the denoiser under test, the history
reprojected as the pass does): over all pixels ("model"), over the pixels whose history passes the
pass's depth/normal tests ("model, tested pixels": the only ones where the model decides anything), and
for the temporal stage as a whole ("temporal stage": failed tests count as certain disocclusion, the
model scores the rest). The dataset's gold is noisy enough that its noise alone flags pixels, so
``--mask-spp N`` also scores against masks from N-spp gold of every pair's frames, raw and compared
after a σ 1.5 px blur (which ignores what noise is left). ``--noise-seeds N`` scores ours and OIDN on
N more 1-spp renders of every test view and prints per-view means: one realization moves a view's gap
by a few tenths of a dB. All networks run in the WGSL engine.

    python benchmarks/bench_denoise.py --data data/dataset [DIR ...] [--models models] [--extra-spp 64 256] [--gold-spp 1024]
        [--per-view] [--noise-seeds 3] [--mask-spp 512] [--skip-denoiser] [--quality balanced high]
        [--oidn-quality fast balanced high]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from common import add_denoiser_step_flags, denoiser_options, equivalent_spp, save_array
from peers import DEVICE_NAMES, QUALITIES, oidn_denoise, oidn_devices, preferred
from wgpu_rt import metrics
from wgpu_rt.frame.denoise import QUALITIES as OUR_QUALITIES
from wgpu_rt.frame.denoise import denoise, load_model
from wgpu_rt.dataset import DatasetConfig, TruthEngine, load_views, plan_views, read_manifest
from wgpu_rt.frame.denoise_chain import trained_auto_exposure
from wgpu_rt.frame.pack import pack_confidence_input, pack_error_input, probe_exposure
from wgpu_rt.nn import WgslModel
from wgpu_rt.train.targets import confidence_pair, disocclusion_mask, error_heatmap
from wgpu_rt.train.trainer import confidence_aucs, rank_correlation

FRAME_SEED_STRIDE = 7919   # frame f > 0 of a reference render: seeds shifted by f times this
NOISE_SEED = 30_000        # --noise-seeds: the k-th realization renders with seed NOISE_SEED + 1000·k + spp
AUC_WAYS = {"roc_auc": "model", "roc_auc_tested": "model, tested pixels", "roc_auc_stage": "temporal stage"}
NOISE_ROBUST_BLUR = 1.5    # σ (pixels) of the --mask-spp mask that ignores gold noise: see disocclusion_mask


def render_test_views(data: Path, view_ids: set[str], spp: list[int], seed: int,
                      frame: int = 0, gbuffers: bool = False) -> dict[str, dict[int, np.ndarray | dict]]:
    """Renders of the test views' ``frame`` at each of ``spp`` (the dataset's scenes, seeds ``seed`` + spp
    (+ FRAME_SEED_STRIDE · frame), independent of the dataset's own renders): the colour, or with
    ``gbuffers`` a dict of colour, albedo, normal and depth rendered as the dataset renders its noisy
    frames (its --aux-samples), the denoisers' input."""
    from wgpu_rt.renderer import render

    config = DatasetConfig.from_record(read_manifest(data)["config"])
    engine = TruthEngine(config, data, renderer=render)
    aux = dict(aovs=("albedo", "normal", "depth"), aux_samples=config.aux_samples) if gbuffers else dict(aovs=())
    result = {}
    for plan in plan_views(config):
        if plan.view_id in view_ids:
            scene = engine.scene_for(plan)
            renders = {s: render(scene, spp=s, size=(config.size, config.size), max_depth=config.max_depth,
                                 seed=seed + s + FRAME_SEED_STRIDE * frame, frames=frame, **aux)
                       for s in spp}
            result[plan.view_id] = {s: ({"color": r.color, **r.aovs} if gbuffers else r.color)
                                    for s, r in renders.items()}
    return result


def reference_gold(data: Path, view_ids: set[str], spp: int, frame: int = 0) -> dict[str, np.ndarray]:
    """A higher-spp gold of the test views' ``frame``, rendered once and kept under DATA/reference/ (so
    that the evaluation is not capped by the dataset gold's own noise)."""
    folder = data / "reference"
    name = lambda v: f"{v}_{spp}spp.npy" if frame == 0 else f"{v}_f{frame}_{spp}spp.npy"  # noqa: E731
    paths = {v: folder / name(v) for v in view_ids}
    missing = {v for v, path in paths.items() if not path.exists()}
    if missing:
        folder.mkdir(exist_ok=True)
        for view_id, images in render_test_views(data, missing, [spp], seed=20_000, frame=frame).items():
            save_array(paths[view_id], np.asarray(images[spp], np.float32))
    return {v: np.load(path) for v, path in paths.items()}


def pair_masks(view, references: dict[int, np.ndarray], blur_sigma: float = 0.0) -> list[np.ndarray]:
    """The disocclusion mask of each of ``view``'s frame pairs from ``references`` (frame → gold)."""
    return [disocclusion_mask(references[t], references[t + 1], view.frames[t + 1].gold["motion"],
                              blur_sigma=blur_sigma)
            for t in range(len(view.frames) - 1)]


def confidence_scores(view, denoiser, confidence_model, masks: dict[str, list[np.ndarray]]) -> dict:
    """ROC AUC of the confidence model on each of ``view``'s frame pairs, per mask, in the three ways the
    module docstring names. Its input is what the temporal pass packs: the current frame's *denoised*
    1-spp render (the pass's source) and the reprojected history (gold frame t standing in for the
    previous output)."""
    scores: dict[str, dict[str, list[float]]] = {}
    for t, (previous, current) in enumerate(zip(view.frames, view.frames[1:])):
        history, history_depth, tested, _ = confidence_pair(previous, current)
        noisy = current.noisy[1]
        source = denoise(denoiser, noisy["color"], noisy["albedo"], noisy["normal"], noisy["depth"])
        x = pack_confidence_input(source, history, noisy["depth"], history_depth)
        confidence = np.asarray(confidence_model(x[None]))[0, 0]
        for name, pairs in masks.items():
            for key, value in confidence_aucs(confidence, pairs[t], tested).items():
                scores.setdefault(name, {}).setdefault(AUC_WAYS[key], []).append(value)
    return scores


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", required=True, nargs="+", metavar="DIR",
                        help="dataset folders; their test views are pooled (gold and references per folder)")
    parser.add_argument("--models", default="models")
    parser.add_argument("--split", default="test")
    parser.add_argument("--precision", default="fp32", choices=["fp32", "fp16"])
    parser.add_argument("--extra-spp", type=int, nargs="*", default=[64],
                        help="brute-force sample counts rendered now, beyond the dataset's")
    parser.add_argument("--gold-spp", type=int, default=None,
                        help="score against a gold rendered at this spp (cached in DATA/reference/) instead of "
                             "the dataset's; the dataset's gold then joins the brute-force rows")
    parser.add_argument("--mask-spp", type=int, default=None,
                        help="also score the confidence model against the mask of every frame pair's gold "
                             "rendered at this spp (cached in DATA/reference/), which flags less gold noise")
    parser.add_argument("--per-view", action="store_true",
                        help="also print each view's PSNR, ours against OIDN")
    parser.add_argument("--noise-seeds", type=int, default=0, metavar="N",
                        help="also score ours and OIDN per view on N more 1-spp renders of each test view (fresh "
                             "seeds, the dataset's aux settings) and print per-view means over them")
    parser.add_argument("--skip-denoiser", action="store_true",
                        help="only the error predictor and the confidence model (no denoiser/OIDN/brute-force "
                             "table, no renders beyond --mask-spp's)")
    parser.add_argument("--quality", nargs="+", default=["balanced"], choices=OUR_QUALITIES,
                        help="rows of ours, one per quality (high: an ensemble of 4 turned passes)")
    parser.add_argument("--oidn-quality", nargs="+", default=["balanced", "high"], choices=QUALITIES,
                        help="OIDN rows, one per quality (on CUDA when benchmarks/peers.py finds it, else the CPU)")
    add_denoiser_step_flags(parser, "image")
    args = parser.parse_args()

    models = Path(args.models)
    denoiser = WgslModel(models / "denoiser.onnx", precision=args.precision)
    error_model = WgslModel(models / "error_predictor.onnx", precision=args.precision)
    confidence_model = WgslModel(models / "confidence.onnx", precision=args.precision)
    devices, skipped = oidn_devices()
    for line in skipped:
        print(line)
    ours = {quality: denoiser if quality == "balanced" else
            load_model("denoiser", args.precision, path=models / "denoiser.onnx", quality=quality)
            for quality in args.quality}
    table = DenoiserTable(preferred(devices), args.oidn_quality, ours, denoiser_options(args))
    spearman = []
    auc: dict[str, dict[str, list[float]]] = {}
    for data in args.data:
        views = load_views(data, args.split)
        view_ids = {v.view_id for v in views}
        dataset_gold_spp = int(read_manifest(data)["config"]["gold"])
        gold_override = reference_gold(Path(data), view_ids, args.gold_spp) if args.gold_spp else {}
        print(f"{len(views)} held-out views ({args.split} split of {data}), "
              f"{views[0].frames[0].gold['color'].shape[1]}² px, precision {args.precision}, gold "
              f"{args.gold_spp or dataset_gold_spp} spp")
        if not args.skip_denoiser:
            table.add_views(args, Path(data), views, gold_override, dataset_gold_spp)
            if args.noise_seeds:
                table.add_noise_seeds(args, Path(data), views, gold_override)

        sequences = {v.view_id for v in views if len(v.frames) > 1}
        mask_references = ({f: reference_gold(Path(data), sequences, args.mask_spp, f)
                            for f in range(max(len(v.frames) for v in views))}
                           if args.mask_spp and sequences else {})
        for view in views:
            noisy = view.frames[0].noisy[1]
            exposure = probe_exposure(noisy["color"]) if trained_auto_exposure(error_model) else 1.0
            heat = np.asarray(error_model(pack_error_input(noisy["color"], exposure)[None]))[0, 0]
            gold = gold_override.get(view.view_id, view.frames[0].gold["color"])
            spearman.append(rank_correlation(heat, error_heatmap(noisy["color"], gold)))
            if view.view_id not in sequences:
                continue
            masks = {f"{dataset_gold_spp}-spp gold mask": pair_masks(view, {t: f.gold["color"]
                                                                            for t, f in enumerate(view.frames)})}
            if mask_references:
                references = {t: mask_references[t][view.view_id] for t in range(len(view.frames))}
                masks[f"{args.mask_spp}-spp gold mask"] = pair_masks(view, references)
                masks[f"{args.mask_spp}-spp gold mask, blurred σ {NOISE_ROBUST_BLUR}"] = pair_masks(
                    view, references, NOISE_ROBUST_BLUR)
            for name, by_way in confidence_scores(view, denoiser, confidence_model, masks).items():
                for way, values in by_way.items():
                    auc.setdefault(name, {}).setdefault(way, []).extend(values)
    if not args.skip_denoiser:
        table.print()
        if args.noise_seeds:
            table.print_noise_seeds()

    print(f"error predictor: Spearman vs true error {np.mean(spearman):.3f} (min {np.min(spearman):.3f})")
    for name, by_way in auc.items():
        print(f"confidence: ROC AUC vs {name} over {len(by_way['model'])} frame pairs: "
              + ", ".join(f"{way} {np.mean(values):.3f}" for way, values in by_way.items()))


class DenoiserTable:
    """The denoiser beside OIDN (each quality, on ``oidn_device``; no OIDN rows when it is None) and brute
    force at rising spp on each view's frame 0, pooled over the dataset folders given, printed as one
    table with equivalent spp and time per view."""

    def __init__(self, oidn_device: str | None, qualities: list[str], ours: dict, options=None):
        """``ours``: quality → our denoiser (WgslModel) at it; the first is the one OIDN is compared with;
        ``options``: denoise()'s (low_band, chroma)."""
        self.oidn_device, self.options = oidn_device, options or {}
        self.ours = {("ours (1 spp)" if quality == "balanced" else f"ours {quality} (1 spp)"): model
                     for quality, model in ours.items()}
        self.OURS = next(iter(self.ours))
        self.oidn = {f"OIDN {quality} (1 spp)": quality for quality in (qualities if oidn_device else [])}
        self.rows: dict[str, list[dict]] = {}
        self.seconds = dict.fromkeys([*self.ours, *self.oidn], 0.0)
        self.views = 0
        self.seeded: dict[str, dict[str, list[float]]] = {}   # view → method → PSNR per noise realization

    def denoisers(self) -> dict:
        """Method name → function of the 1-spp images returning the denoised colour."""
        ours = {name: lambda noisy, model=model: denoise(model, noisy["color"], noisy["albedo"], noisy["normal"],
                                                         noisy["depth"], **self.options)
                for name, model in self.ours.items()}
        return ours | {name: lambda noisy, quality=quality: oidn_denoise(noisy["color"], noisy["albedo"],
                                                                         noisy["normal"], quality, self.oidn_device)
                       for name, quality in self.oidn.items()}

    def add_views(self, args, data: Path, views, gold_override: dict, dataset_gold_spp: int) -> None:
        extra = (render_test_views(data, {v.view_id for v in views}, args.extra_spp, seed=10_000)
                 if args.extra_spp else {})
        denoisers = self.denoisers()
        if not self.views:   # warm-up: pipeline compilation and OIDN's set-up are not denoising time
            for run in denoisers.values():
                run(views[0].frames[0].noisy[1])
        for view in views:
            frame = view.frames[0]
            gold, noisy = gold_override.get(view.view_id, frame.gold["color"]), frame.noisy[1]
            candidates = {}
            for name, run in denoisers.items():
                started = time.perf_counter()
                candidates[name] = run(noisy)
                self.seconds[name] += time.perf_counter() - started
            for spp, render in sorted({**{s: frame.noisy[s]["color"] for s in view.spp},
                                       **extra.get(view.view_id, {})}.items()):
                candidates[f"brute {spp} spp"] = render
            if gold_override:
                candidates[f"dataset gold {dataset_gold_spp}"] = frame.gold["color"]
            for name, image in candidates.items():
                self.rows.setdefault(name, []).append(metrics.all_metrics(gold, image))
            self.views += 1
            if args.per_view:
                psnr = {name: self.rows[name][-1]["psnr"] for name in denoisers}
                print(f"  {data}/{view.view_id} {view.scene:15s} PSNR ours {psnr[self.OURS]:6.2f}"
                      + "".join(f", {name.removesuffix(' (1 spp)')} {value:6.2f} ({value - psnr[self.OURS]:+.2f} dB)"
                                for name, value in psnr.items() if name != self.OURS))

    def add_noise_seeds(self, args, data: Path, views, gold_override: dict) -> None:
        """Each view's PSNR per method over its dataset render and --noise-seeds fresh 1-spp renders (the
        dataset's aux settings, seeds NOISE_SEED + 1000·k): a per-view gap to OIDN that one realization's
        noise does not decide."""
        denoisers = self.denoisers()
        fresh = [render_test_views(data, {v.view_id for v in views}, [1], seed=NOISE_SEED + 1000 * k, gbuffers=True)
                 for k in range(args.noise_seeds)]
        for view in views:
            gold = gold_override.get(view.view_id, view.frames[0].gold["color"])
            scores = self.seeded.setdefault(f"{data}/{view.view_id} {view.scene}", {})
            for noisy in [view.frames[0].noisy[1], *(renders[view.view_id][1] for renders in fresh)]:
                for name, run in denoisers.items():
                    scores.setdefault(name, []).append(metrics.psnr(gold, run(noisy)))

    def print_noise_seeds(self) -> None:
        """Per view and method the mean PSNR over the realizations, the gap of each OIDN quality to ours,
        and the mean and worst gap over the views."""
        first = next(iter(self.seeded.values()))
        short = lambda name: name.removesuffix(" (1 spp)")  # noqa: E731
        print(f"PSNR over {len(first[self.OURS])} noise realizations per view (the dataset's 1-spp render and "
              f"{len(first[self.OURS]) - 1} fresh ones): mean, and each other method's lead over {short(self.OURS)}")
        mean = {view: {name: float(np.mean(values)) for name, values in scores.items()}
                for view, scores in self.seeded.items()}
        for view, scores in mean.items():
            ours = scores[self.OURS]
            print(f"  {view:40s} {short(self.OURS)} {ours:6.2f}" + "".join(
                f", {short(name)} {value:6.2f} ({value - ours:+.2f} dB)" for name, value in scores.items()
                if name != self.OURS))
        print("  mean PSNR " + ", ".join(f"{short(name)} {np.mean([m[name] for m in mean.values()]):.2f}"
                                         for name in first))
        for ours in self.ours:
            for name in self.oidn:
                gaps = [m[name] - m[ours] for m in mean.values()]
                print(f"  {short(name)} ahead of {short(ours)} by {np.mean(gaps):+.2f} dB on average, "
                      f"{max(gaps):+.2f} on the worst view, on {sum(g > 0 for g in gaps)} of {len(gaps)} views")

    def print(self) -> None:
        rows = self.rows
        keys = list(rows[self.OURS][0])
        print(f"{'method':22s}" + "".join(f"{k:>10s}" for k in keys) + "     views")
        means = {name: {k: float(np.mean([r[k] for r in values])) for k in keys} for name, values in rows.items()}
        for name, m in means.items():
            print(f"{name:22s}" + "".join(f"{m[k]:10.4f}" for k in keys) + f"{len(rows[name]):10d}")
        brute = sorted((int(n.split()[1]), m) for n, m in means.items()
                       if n.startswith("brute") and len(rows[n]) == self.views)
        display_mse = lambda m: 10 ** (-m["psnr"] / 10)  # noqa: E731  (the MSE behind the PSNR)
        for name in self.seconds:
            by_rel_mse = equivalent_spp([b for b, _ in brute], [m["rel_mse"] for _, m in brute], means[name]["rel_mse"])
            by_psnr = equivalent_spp([b for b, _ in brute], [display_mse(m) for _, m in brute], display_mse(means[name]))
            print(f"equivalent spp of {name}: {by_rel_mse} by relMSE, {by_psnr} by PSNR")
        ours = self.seconds[self.OURS] / self.views
        print(f"time per view: ours {ours:.3f} s (WGSL on the adapter)"
              + "".join(f"; {name.removesuffix(' (1 spp)')} {seconds / self.views:.3f} s"
                        + (f" ({DEVICE_NAMES[self.oidn_device]})" if name in self.oidn else "")
                        + f", ours ÷ it {self.seconds[self.OURS] / max(seconds, 1e-9):.2f}"
                        for name, seconds in self.seconds.items() if name != self.OURS))


if __name__ == "__main__":
    main()
