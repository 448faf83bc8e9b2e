"""Fused frame pipeline cost: per-stage GPU time (timestamp queries) and wall time per frame of
denoise (+ adaptive, + temporal) against the plain 1-spp trace measured in the same run; the fused
pipeline again reading back only the display image (``hdr=False``: what a viewer needs; the other rows also
read back the linear HDR colour, 12 bytes a pixel); on frames that take the denoiser's half-resolution low
band (256 pixels a side and up), the fused pipeline without it too.

Frames are consumed as a real-time caller would (each dropped before the next arrives; keeping them all
would time the operating system handing out fresh pages); ``--host-ms`` adds a caller's own work per
frame (sleeping, e.g. for a display or an encoder), which the next frame's device work should hide. "wall
− GPU" is the wall time per frame beyond the frame's GPU stages (the issue's real-time target: ≤ 1 ms).

Each row's renderer renders one untimed frame first; before the first row, ``--warm-up`` fused frames
are rendered and thrown away: on an H200 the first row of a process had measured the denoiser at 9.9 ms
a frame and every later row at 7.5 (BENCHMARKS.md §25).

Needs the trained models in models/ (denoiser.onnx; error_predictor.onnx for --adaptive).
    python3 benchmarks/bench_pipeline.py --size 128x128 --frames 8 [--adaptive 4] [--temporal] [--host-ms 5]
        [--warm-up 8]
"""

import argparse
import time

import numpy as np

from common import image_size
from wgpu_rt.frame.lowband import uses_low_band
from wgpu_rt.renderer import Renderer
from wgpu_rt.scene import load_scene


def timed(scene, frames, host_ms=0.0, **settings):
    """Wall time per frame after the set-up and one warm-up frame, the GPU time per stage and of a whole
    frame, each the mean over the frames, like the wall time: stages some frames leave out (the low band
    once a static camera has accumulated LOW_BAND_MAX_SPP samples) count 0 in the others."""
    renderer = Renderer(scene, **settings)
    list(renderer.frames(0))                                            # compile and warm up
    stage_ms = []
    start = time.perf_counter()
    for result in renderer.frames(frames):
        stage_ms.append(result.stage_ms)
        time.sleep(host_ms / 1e3)
    per_frame = (time.perf_counter() - start) / len(frames)
    names = list(dict.fromkeys(name for s in stage_ms for name in s))   # in order, every frame's
    stages = {name: round(float(np.mean([s.get(name, 0.0) for s in stage_ms])), 3) for name in names}
    gpu = float(np.mean([sum(s.values()) for s in stage_ms])) / 1e3
    return per_frame, stages, gpu


def line(name, per_frame, stages, gpu):
    return (f"{name:19s}: {per_frame * 1e3:8.1f} ms/frame  GPU {gpu * 1e3:.1f}  "
            f"wall − GPU {(per_frame - gpu) * 1e3:.1f}  stages {stages}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="moving")
    parser.add_argument("--size", type=image_size, default="128x128")
    parser.add_argument("--frames", type=int, default=8)
    parser.add_argument("--adaptive", type=float)
    parser.add_argument("--temporal", action="store_true")
    parser.add_argument("--host-ms", type=float, default=0.0, help="the caller's own work per frame (a sleep)")
    parser.add_argument("--warm-up", type=int, default=8, metavar="FRAMES",
                        help="fused frames rendered and thrown away before the first timed row (default 8)")
    args = parser.parse_args()
    width, height = args.size
    scene = load_scene(args.scene)
    common = dict(size=(width, height), frames=range(args.frames), host_ms=args.host_ms, max_depth=8, aovs=(),
                  tonemap="aces")
    if args.warm_up:
        timed(scene, denoise=True, adaptive=args.adaptive, temporal=args.temporal,
              **{**common, "frames": range(args.warm_up)})
    plain = timed(scene, denoise=False, **common)
    fused = timed(scene, denoise=True, adaptive=args.adaptive, temporal=args.temporal, **common)
    print(f"{args.scene} {width}x{height}, {args.frames} frames, the caller's own work {args.host_ms:g} ms a frame")
    print(line("plain 1-spp trace", *plain))
    print(line("fused pipeline", *fused))
    print(f"ratio fused/plain : {fused[0] / plain[0]:.2f}")
    display_only = timed(scene, denoise=True, adaptive=args.adaptive, temporal=args.temporal, hdr=False, **common)
    print(line("fused, display only", *display_only) + "  (hdr=False: no linear HDR colour read back, as a "
          "viewer needs)")
    if uses_low_band(width, height):
        bare = timed(scene, denoise=True, adaptive=args.adaptive, temporal=args.temporal, low_band=False, **common)
        print(line("fused, no low band", *bare))
        print(f"ratio fused/plain : {bare[0] / plain[0]:.2f} without the low band")


if __name__ == "__main__":
    main()
