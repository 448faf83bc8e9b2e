"""Fused frame pipeline cost: per-stage GPU time (timestamp queries) and wall time per frame of
denoise (+ adaptive, + temporal) against the plain 1-spp trace measured in the same run; on frames that
take the denoiser's half-resolution low band (256 pixels a side and up), the fused pipeline without it too.

Needs the trained models in models/ (denoiser.onnx; error_predictor.onnx for --adaptive).
    python3 benchmarks/bench_pipeline.py --size 128x128 --frames 8 [--adaptive 4] [--temporal]
"""

import argparse
import time

import numpy as np

from wgpu_rt.frame.lowband import uses_low_band
from wgpu_rt.renderer import Renderer, parse_size
from wgpu_rt.scene import load_scene


def timed(scene, frames, **settings):
    """Wall time per frame after the set-up and one warm-up frame, and the median GPU time per stage."""
    renderer = Renderer(scene, **settings)
    list(renderer.frames(0))                                            # compile and warm up
    start = time.perf_counter()
    out = list(renderer.frames(frames))
    per_frame = (time.perf_counter() - start) / len(frames)
    stages = {name: round(float(np.median([f.stage_ms.get(name, 0.0) for f in out])), 3) for name in out[-1].stage_ms}
    return per_frame, stages


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="moving")
    parser.add_argument("--size", default="128x128")
    parser.add_argument("--frames", type=int, default=8)
    parser.add_argument("--adaptive", type=float)
    parser.add_argument("--temporal", action="store_true")
    args = parser.parse_args()
    width, height = parse_size(args.size)
    scene = load_scene(args.scene)
    common = dict(size=(width, height), frames=range(args.frames), max_depth=8, aovs=(), tonemap="aces")
    plain, plain_stages = timed(scene, denoise=False, **common)
    fused, fused_stages = timed(scene, denoise=True, adaptive=args.adaptive, temporal=args.temporal, **common)
    print(f"{args.scene} {width}x{height}, {args.frames} frames")
    print(f"plain 1-spp trace : {plain * 1e3:8.1f} ms/frame  stages {plain_stages}")
    print(f"fused pipeline    : {fused * 1e3:8.1f} ms/frame  stages {fused_stages}")
    print(f"ratio fused/plain : {fused / plain:.2f}")
    if uses_low_band(width, height):
        bare, bare_stages = timed(scene, denoise=True, adaptive=args.adaptive, temporal=args.temporal,
                                  low_band=False, **common)
        print(f"fused, no low band: {bare * 1e3:8.1f} ms/frame  stages {bare_stages}")
        print(f"ratio fused/plain : {bare / plain:.2f} without the low band")


if __name__ == "__main__":
    main()
