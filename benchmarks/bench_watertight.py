"""What the watertight intersection costs: samples/s of the shipped box and triangle tests against the
forms they replaced (issue 13 item 6), same scenes, same run.

The shipped tests (wgsl/accel/walk_tree.wgsl): box slabs as (plane − origin) · (1/dir), ray-space x and y as
explicit fma chains, and an edge function that is exactly antisymmetric under any contraction. The
pre-fix forms: slabs as one fma per plane (plane · (1/dir) − origin · (1/dir), which cancels when the
origin is far from the box), ray-space coordinates as dot products and the edge function as
p.x·q.y − p.y·q.x (which lets rays through shared edges where a driver fuses it). Each variant is the
shipped shader with those lines swapped in; only the shipped one is watertight (tests/test_bvh.py).

    python3 benchmarks/bench_watertight.py [--size 1024] [--spp 64] [--scenes bunny cornell cornell-glossy]
"""

import argparse
import sys

from common import load_scenes, print_header

from wgpu_rt import shaders
from wgpu_rt.renderer import render

BVH_MODULE = "accel/walk_tree.wgsl"
SHIPPED = {
    "slab": ("    let t0 = (lo - ray.origin) * ray.inv_dir;\n"
             "    let t1 = (hi - ray.origin) * ray.inv_dir;"),
    "ray space": ("    return vec2f(fma(ray.shear_x.z, v.z, fma(ray.shear_x.y, v.y, ray.shear_x.x * v.x)),\n"
                  "                 fma(ray.shear_y.z, v.z, fma(ray.shear_y.y, v.y, ray.shear_y.x * v.x)));"),
    "edge": "    return fma(p.x, q.y, -(p.y * q.x)) - fma(q.x, p.y, -(q.y * p.x));",
}
PRE_FIX = {
    "slab": ("    let origin_scaled = ray.origin * ray.inv_dir;\n"
             "    let t0 = fma(lo, ray.inv_dir, -origin_scaled);\n"
             "    let t1 = fma(hi, ray.inv_dir, -origin_scaled);"),
    "ray space": "    return vec2f(dot(ray.shear_x, v), dot(ray.shear_y, v));",
    "edge": "    return p.x * q.y - p.y * q.x;",
}
VARIANTS = {"shipped": (), "pre-fix triangle": ("ray space", "edge"), "pre-fix slab": ("slab",),
            "pre-fix both": ("slab", "ray space", "edge")}


def reader_with(swapped: tuple[str, ...]):
    """shaders.read_wgsl with the pre-fix forms of ``swapped`` in accel/walk_tree.wgsl."""
    read = shaders.read_wgsl

    def read_swapped(name: str, package=shaders.PATH_TRACING) -> str:
        text = read(name, package)
        if name == BVH_MODULE:
            for part in swapped:
                if SHIPPED[part] not in text:
                    raise SystemExit(f"{BVH_MODULE} no longer holds the shipped {part} test this benchmark swaps")
                text = text.replace(SHIPPED[part], PRE_FIX[part])
        return text
    return read_swapped


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--scenes", nargs="+", default=["bunny", "cornell", "cornell-glossy"])
    parser.add_argument("--repeats", type=int, default=2, help="timed renders per row; the best counts")
    args = parser.parse_args()
    print_header(args)
    size = (args.size, args.size)
    shipped_reader = shaders.read_wgsl
    print(f"{'scene':15} {'variant':17} {'M samples/s':>11} {'÷ shipped':>9}")
    for scene in load_scenes(args.scenes):
        shipped_rate = None
        for name, swapped in VARIANTS.items():
            shaders.read_wgsl = reader_with(swapped)
            try:
                render(scene, spp=1, size=size, max_depth=8, aovs=())   # compiles this variant
                seconds = min(render(scene, spp=args.spp, size=size, max_depth=8, aovs=()).seconds
                              for _ in range(args.repeats))
            finally:
                shaders.read_wgsl = shipped_reader
            rate = args.spp * args.size * args.size / seconds
            shipped_rate = shipped_rate or rate
            print(f"{scene.name:15} {name:17} {rate / 1e6:11.1f} {rate / shipped_rate:9.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
