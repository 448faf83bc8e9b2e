"""Specialized vs all-features tracing kernel on a diffuse-only scene (`cornell`): samples/s of each,
measured in the same run, and the ratio (specialized / all-features; above 1 means the
specialization pays).

    python3 benchmarks/bench_specialization.py [--spp 32] [--size 128]
"""

import argparse
import sys
import time

from common import print_header

from wgpu_rt.gpu import get_context
from wgpu_rt.passes import FrameBuffers
from wgpu_rt.scene import load_scene
from wgpu_rt.accel.geometry import GeometryBuffers
from wgpu_rt.trace import SampleSchedule, SceneFeatures, TracePass


def best_times(ctx, passes: dict, size, spp, rounds=4) -> dict:
    """Best wall time per pass over ``rounds``, the passes alternating so that load from other
    processes falls on both alike."""
    best = {name: float("inf") for name in passes}
    for _ in range(rounds):
        for name, trace in passes.items():
            buffers = FrameBuffers(ctx, *size)
            encoder = ctx.device.create_command_encoder()
            trace.execute(encoder, buffers, SampleSchedule(samples=spp))
            started = time.perf_counter()
            ctx.device.queue.submit([encoder.finish()])
            buffers.read("spp")
            best[name] = min(best[name], time.perf_counter() - started)
    return best


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spp", type=int, default=32)
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--scene", default="cornell")
    args = parser.parse_args()
    print_header(args)
    ctx = get_context()
    scene = load_scene(args.scene)
    geometry = GeometryBuffers.build(scene)
    size = (args.size, args.size)
    specialized_features = SceneFeatures.of(scene)
    passes = {"all-features": TracePass(ctx, scene, geometry, *size, features=SceneFeatures.everything()),
              "specialized": TracePass(ctx, scene, geometry, *size, features=specialized_features)}
    seconds = best_times(ctx, passes, size, args.spp)
    full, specialized = (args.spp * size[0] * size[1] / seconds[n] for n in ("all-features", "specialized"))
    print(f"{args.scene} {size[0]}x{size[1]} {args.spp} spp: all-features {full / 1e6:.3f} M samples/s, "
          f"specialized ({specialized_features}) {specialized / 1e6:.3f} M samples/s, "
          f"ratio {specialized / full:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
