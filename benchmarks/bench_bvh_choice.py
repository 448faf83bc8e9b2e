"""What the measured BVH choice (wgpu_rt.trace.bvh_choice, WGPU_RT_BVH=auto) picks on this adapter, each
variant's probe time, and what the measurement costs the first render of a scene size.

Per scene, on a fresh choices cache: a 64² 1-spp render with the threaded walk forced (twice: the first
compiles), then the same with auto (the first measures every variant: it compiles the others and traces
the probes; the second reads the cache). The extra seconds of auto's first render are the measurement's
whole cost; later renders of any scene of that size pay nothing.

    python3 benchmarks/bench_bvh_choice.py [--scenes bunny world-2147483670 cornell-glossy]
"""

import argparse
import json
import os
import sys
import tempfile
import time

from common import load_scenes, print_header

from wgpu_rt.accel.geometry import BVH_LAYOUT_ENV
from wgpu_rt.measured_choices import CACHE_DIR_ENV, cache_path
from wgpu_rt.renderer import render


def seconds_of_render(scene) -> float:
    started = time.perf_counter()
    render(scene, spp=1, size=(64, 64), aovs=())
    return time.perf_counter() - started


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["bunny", "world-2147483670", "cornell-glossy"])
    args = parser.parse_args()
    print_header(args)
    for scene in load_scenes(args.scenes):
        triangles = sum(len(mesh.faces) for mesh in scene.meshes)
        with tempfile.TemporaryDirectory() as cache:
            os.environ[CACHE_DIR_ENV] = cache
            times = {}
            for mode in ("threaded", "auto"):
                os.environ[BVH_LAYOUT_ENV] = mode
                times[mode] = (seconds_of_render(scene), seconds_of_render(scene))
            entries = json.loads(cache_path().read_text())["entries"].values() if cache_path().exists() else []
        probes = "; ".join(f"took {entry['variant']}, probes " + ", ".join(
            f"{variant} {seconds * 1e3:.1f} ms" for variant, seconds in entry["seconds"].items())
            for entry in entries) or "not measured (too few triangles)"
        print(f"{scene.name} ({triangles:,} triangles): {probes}; first / second render threaded "
              f"{times['threaded'][0]:.2f} / {times['threaded'][1]:.2f} s, auto {times['auto'][0]:.2f} / "
              f"{times['auto'][1]:.2f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
