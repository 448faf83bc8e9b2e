"""Tracing throughput: samples/s on `cornell` (256², max depth 8) for wgpu-rt and for Mitsuba 3 in its
fastest variant here (cuda_ad_rgb with a CUDA GPU, else llvm_ad_rgb when LLVM 19 is installed, else
scalar_rgb: benchmarks/peers.py) measured in the same run, and their ratio; a faster variant that is
absent prints one "skipped (why)" line. Compile time is excluded on both sides (one warm-up render
each), and so is the scene set-up (our BVH build and uploads, printed on a line of their own; Mitsuba's
scene load). ``--scene bunny`` is the `mesh` scene with ../shared/meshes' Stanford bunny. ``--layouts``
traces with each BVH variant in turn (wgpu_rt.accel.geometry.bvh_variants: a node layout, "+rows" for
16-byte row loads; or ``auto``: the one measured fastest on this adapter, wgpu_rt.trace.bvh_choice,
printed as "auto: VARIANT"; default: what WGPU_RT_BVH selects, else auto).

    python3 benchmarks/bench_trace.py [--spp 64] [--size 256] [--scene cornell] [--layouts threaded wide wide+rows auto]
"""

import argparse
import os
import sys

from common import load_scenes, print_header
from peers import mitsuba_peer, time_mitsuba

from wgpu_rt.accel.geometry import BVH_LAYOUT_ENV, LANES_TRAVERSAL, GeometryBuffers, bvh_layout, bvh_variants
from wgpu_rt.renderer import render


def layout_label(layout: str, scene, max_depth: int) -> str:
    """``layout``, or for auto the layout it took (read from the choices cache its render filled)."""
    if layout != "auto":
        return layout
    from wgpu_rt.gpu import get_context
    from wgpu_rt.trace.bvh_choice import choose_layout

    return f"auto: {choose_layout(get_context(), scene, GeometryBuffers.build(scene), max_depth).variant}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--scene", default="cornell")
    parser.add_argument("--max-depth", type=int, default=8)
    parser.add_argument("--layouts", nargs="+", choices=["auto", *bvh_variants(LANES_TRAVERSAL)], default=None)
    args = parser.parse_args()
    print_header(args)
    size, samples = (args.size, args.size), args.spp * args.size * args.size
    scenes = load_scenes([args.scene])
    if not scenes:
        return 1
    scene = scenes[0]

    rates, setups = {}, {}
    for layout in args.layouts or [bvh_layout()]:
        os.environ[BVH_LAYOUT_ENV] = layout
        render(scene, spp=1, size=size, max_depth=args.max_depth, aovs=())
        ours = render(scene, spp=args.spp, size=size, max_depth=args.max_depth, aovs=())
        label = layout_label(layout, scene, args.max_depth)
        rates[label], setups[label] = samples / ours.seconds, ours.setup_seconds

    mi, skipped = mitsuba_peer()
    for line in skipped:
        print(line)
    line = (f"{args.scene} {size[0]}x{size[1]} {args.spp} spp max depth {args.max_depth}: wgpu-rt "
            + ", ".join(f"{rate / 1e6:.3f} M samples/s ({layout} BVH)" for layout, rate in rates.items()))
    if mi is not None:
        _, seconds = time_mitsuba(mi, scene, size, args.spp, args.max_depth)
        mi_rate = samples / seconds
        line += (f", Mitsuba {mi.variant()} {mi_rate / 1e6:.3f} M samples/s, ratio "
                 + ", ".join(f"{rate / mi_rate:.3f} ({layout})" for layout, rate in rates.items()))
    print(line)
    # set-up is not in the rates above (nor in Mitsuba's: its scene load is not timed); for reference
    print("set-up (renderer, BVH, uploads; kernels compiled by the warm-up): "
          + ", ".join(f"{seconds:.3f} s ({layout})" for layout, seconds in setups.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
