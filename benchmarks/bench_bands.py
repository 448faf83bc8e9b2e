"""The denoise chain in bands of rows (wgpu_rt/frame/bands.py) against the same frame whole, on one adapter.

A frame whose packed denoiser input is wider than one storage binding runs pack, network, unpack and the post
filter in bands with the network's reach of context either side. To set the bands' cost beside the whole
frame's at one size, the device's binding limit is lowered to ``--binding-mib`` for the banded run (the same
device): a `cornell` frame at ``--size`` (1 spp, the aux pass's albedo) goes through ``denoise()`` whole and in
bands, each timed as the best of ``--repeats`` after a first call that builds the passes. Printed: the band plan
(rows read and kept), both times, their ratio, the rows the bands read over the frame's rows (the network's
extra work), and the largest difference between the two images (the kept rows equal the whole frame's).

    python3 benchmarks/bench_bands.py --size 1920x1080 --binding-mib 64
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", default="1920x1080", help="WIDTHxHEIGHT (default 1920x1080)")
    parser.add_argument("--binding-mib", type=int, default=64,
                        help="the binding limit of the banded run, MiB (default 64)")
    parser.add_argument("--repeats", type=int, default=2, help="timed calls after the first (default 2)")
    args = parser.parse_args()

    from wgpu_rt.frame.denoise import DenoiseOnDevice, denoise, load_model
    from wgpu_rt.gpu import GpuContext, get_context
    from wgpu_rt.renderer import render

    width, height = (int(v) for v in args.size.lower().split("x"))
    gpu = get_context()
    narrow = GpuContext(gpu.adapter, gpu.device, gpu.features)
    narrow.__dict__["limits"] = {**gpu.limits, "max-storage-buffer-binding-size": args.binding_mib << 20}
    frame = render("cornell", spp=1, size=(width, height), ctx=gpu, aovs=("albedo", "normal", "depth"),
                   aux_samples=4)
    layers = [frame.aovs[name] for name in ("albedo", "normal", "depth")]
    print(f"adapter: {gpu.label}; cornell {width}×{height}, 1 spp; bands under a {args.binding_mib} MiB binding")
    seconds, images = {}, {}
    for name, ctx in (("whole", gpu), ("bands", narrow)):
        model = load_model("denoiser", "fp32", ctx=ctx)
        images[name] = denoise(model, frame.color, *layers, 1)
        chain = next(iter(DenoiseOnDevice._made[model].values())).chain
        if (chain.bands is None) != (name == "whole"):
            raise SystemExit(f"{name}: the chain {'did not run' if name == 'bands' else 'ran'} in bands; "
                             "choose another --binding-mib")
        times = []
        for _ in range(args.repeats):
            started = time.perf_counter()
            denoise(model, frame.color, *layers, 1)
            times.append(time.perf_counter() - started)
        seconds[name] = min(times)
        if chain.bands is not None:
            bands = chain.bands.bands
            print("bands (rows read → kept): " + ", ".join(f"{b.top}–{b.bottom} → {b.start}–{b.stop}" for b in bands))
            print(f"rows read over the frame's: {sum(b.rows for b in bands) / height:.2f}×")
    print(f"whole {seconds['whole']:.2f} s, bands {seconds['bands']:.2f} s: {seconds['bands'] / seconds['whole']:.2f}×")
    print(f"largest difference: {np.abs(images['bands'] - images['whole']).max():.3g}")


if __name__ == "__main__":
    main()
