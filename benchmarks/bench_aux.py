"""Noise-free albedo (the aux pass) for the denoisers: PSNR of ours and OIDN at 1 spp with the tracer's
own albedo (aux 0) and with the albedo re-estimated from N delta-chain paths per pixel (F·N in pixels
whose paths meet a mirror or smooth glass: --delta-factor F, default the renderer's), on the built-in
scenes with glass or none and on held-out generated worlds that hold glass; and the aux pass's GPU time
against the 1-spp trace's (timestamp queries).

    python3 benchmarks/bench_aux.py --size 96 --gold-spp 1024 --aux 0 1 2 4 8 --worlds 4 [--delta-factor 1]
"""

from __future__ import annotations

import argparse

import numpy as np

from common import (add_gold_arguments, add_model_arguments, errors, gold_render, load_scenes, denoiser_options, oidn,
                    parse_with_quick_defaults, print_header, print_table, resolve_models)
from wgpu_rt.trace import trace_pass


def glass_worlds(count: int) -> list:
    """The first ``count`` held-out worlds with a glass material (none trained on)."""
    from wgpu_rt.dataset.worlds import generate_world

    found, seed = [], 2 ** 31
    while len(found) < count:
        world = generate_world(seed)
        if any(m.kind == "dielectric" for m in world.materials.values()):
            found.append(world)
        seed += 1
    return found


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["cornell", "cornell-glossy"])
    parser.add_argument("--worlds", type=int, default=4, help="held-out worlds with glass")
    parser.add_argument("--size", type=int, default=96)
    parser.add_argument("--aux", type=int, nargs="+", default=[0, 1, 2, 4, 8])
    parser.add_argument("--max-depth", type=int, default=8)
    parser.add_argument("--delta-factor", type=int, default=trace_pass.AUX_DELTA_FACTOR,
                        help="aux samples behind mirrors and glass, per aux sample elsewhere (1: the same "
                             "everywhere; default: %(default)s, the renderer's)")
    add_gold_arguments(parser, 1024)
    add_model_arguments(parser)
    args = parse_with_quick_defaults(parser, {"size": 48, "worlds": 1, "gold_spp": 256, "aux": [0, 4]})
    resolve_models(args)
    print_header(args)
    trace_pass.AUX_DELTA_FACTOR = args.delta_factor   # read by TracePass.execute_aux at each call
    from wgpu_rt.renderer import Renderer

    size = (args.size, args.size)
    rows, times, others = [], [], []
    for scene in load_scenes(args.scenes) + glass_worlds(args.worlds):
        gold = gold_render(scene, size, args)
        row = [scene.name]
        for aux in args.aux:
            options = dict(size=size, max_depth=args.max_depth, seed=7, aux_samples=aux)
            ours = Renderer(scene, denoise=True, aovs=("albedo", "normal"), models_dir=args.models,
                            precision=args.precision, **denoiser_options(args), **options)
            result = next(ours.frames())
            ours_errors = errors(gold, result.color)
            row.append(ours_errors["PSNR"])
            if aux in (0, max(args.aux)):
                noisy = next(Renderer(scene, aovs=(), **options).frames()).color   # the same 1-spp colour
                oidn_errors = errors(gold, oidn(noisy, result.aovs["albedo"], result.aovs["normal"]))
                row.append(oidn_errors["PSNR"])
                if aux == max(args.aux):
                    others.append([scene.name, *(e.get(m, float("nan")) for m in ("relMSE", "FLIP")
                                                 for e in (ours_errors, oidn_errors))])
            if aux == max(args.aux) and "aux" in result.stage_ms:
                steady = [next(ours.frames(f)).stage_ms for f in (1, 2, 3)]
                times.append([scene.name, aux, float(np.median([s["trace"] for s in steady])),
                              float(np.median([s["aux"] for s in steady]))])
        rows.append(row)
    headers = ["scene"]
    for aux in args.aux:
        headers.append(f"ours aux {aux}")
        if aux in (0, max(args.aux)):
            headers.append(f"OIDN aux {aux}")
    print_table(f"PSNR (dB) at 1 spp against {args.gold_spp}-spp gold, {args.size}² (aux N: albedo from N "
                f"delta-chain paths, {args.delta_factor}·N behind mirrors and glass; 0: the tracer's own)",
                headers, rows)
    print_table(f"relMSE and FLIP at aux {max(args.aux)} (lower is better)",
                ["scene", "ours relMSE", "OIDN relMSE", "ours FLIP", "OIDN FLIP"],
                others + [["mean", *np.mean([row[1:] for row in others], axis=0)]])
    if times:
        print_table("GPU time per frame (median of 3, ms)", ["scene", "aux samples", "1-spp trace", "aux pass",
                                                             "aux / trace"], [[*t, t[3] / t[2]] for t in times])


if __name__ == "__main__":
    main()
