"""BVH build time and size for 10k / 100k / 1M triangles and the Stanford bunny, plus GPU traversal
throughput (closest-hit rays per second through wgsl/accel/ray_query.wgsl) with each traversal module:
`lanes` (every invocation walks alone) and `packet` (a subgroup walks together, on CPU adapters with
subgroups), both over the threaded binary layout, and `wide` and `wide packet`, the same two over the
4-wide layout (wgsl/accel/walk_wide.wgsl); `lanes rows` and `wide rows` are `lanes` and `wide` with
nodes and vertices fetched as 16-byte rows (wgsl/accel/geometry_rows.wgsl); `wide8` and `wide8 rows`
the wide ones with child boxes quantized to 8 bits (64-byte nodes). The rays start at random points all
around the mesh, so neighbouring invocations share nothing: the worst case for packets, which the path
tracer's neighbouring pixels are not.

Peer: Mitsuba 3 (scalar_rgb, or where the build has none, as on the lent GPUs, cuda_ad_rgb:
wgpu_rt.scene.mitsuba.use_variant) loading a scene that holds the same triangles, which includes building
its own acceleration structure, timed in the same run; the last column is Mitsuba's time over ours
(> 1: we build faster). Run: ``python3 benchmarks/bench_bvh.py [--sizes 10000,100000,1000000]``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from wgpu_rt.accel.bvh import build_bvh
from wgpu_rt.accel.geometry import LANES_TRAVERSAL, SUBGROUP_TRAVERSAL

# Columns: name, traversal module, BVH variant (accel.geometry.bvh_variants).
WALKS = (("lanes", LANES_TRAVERSAL, "threaded"), ("packet", SUBGROUP_TRAVERSAL, "threaded"),
         ("wide", LANES_TRAVERSAL, "wide"), ("wide packet", SUBGROUP_TRAVERSAL, "wide"),
         ("lanes rows", LANES_TRAVERSAL, "threaded+rows"), ("wide rows", LANES_TRAVERSAL, "wide+rows"),
         ("wide8", LANES_TRAVERSAL, "wide8"), ("wide8 rows", LANES_TRAVERSAL, "wide8+rows"))

BUNNY = Path(__file__).resolve().parents[1].parent / "shared" / "meshes" / "stanford-bunny.obj"


def random_soup(count: int, seed: int = 0) -> np.ndarray:
    """``count`` small random triangles in a unit cube (edge ~ 2/cbrt(count))."""
    rng = np.random.default_rng(seed)
    size = 2.0 / np.cbrt(count)
    return (rng.uniform(-1, 1, (count, 1, 3)) + rng.normal(0, size, (count, 3, 3))).astype(np.float32)


def best_of(repeats: int, fn) -> tuple[float, object]:
    best, result = np.inf, None
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - start)
    return best, result


def mitsuba_load_seconds(triangles: np.ndarray) -> float | None:
    try:
        import mitsuba as mi
    except ImportError:
        return None
    from wgpu_rt.scene.model import Camera, Material, Mesh, Scene
    from wgpu_rt.scene.mitsuba import to_mitsuba, use_variant

    if use_variant(mi) is None:
        return None

    faces = np.arange(3 * len(triangles), dtype=np.uint32).reshape(-1, 3)
    scene = Scene(Camera([0, 0, 3], [0, 0, 0]), [Mesh("m", triangles.reshape(-1, 3), faces, "grey")],
                  {"grey": Material()})
    converted = to_mitsuba(scene, 8, 8, 1, 2)
    seconds, _ = best_of(2, lambda: mi.load_dict(converted))
    return seconds


def traversal_rate(triangles: np.ndarray, traversal: str, layout: str = "threaded",
                   rays: int = 512 * 512) -> float | None:
    """Closest-hit rays per second on the GPU for rays from random outside points toward the mesh,
    walked with the traversal module ``traversal`` over the BVH variant ``layout`` (None when the adapter cannot
    run it)."""
    from wgpu_rt.errors import NoAdapterError
    from wgpu_rt.gpu import get_context
    from wgpu_rt.accel.geometry import GeometryBuffers, traversal_module
    from wgpu_rt.scene.model import Camera, Material, Mesh, Scene
    from wgpu_rt.accel.ray_query import HIT_DTYPE, SURFACE_DTYPE, RayQuery, query_rays

    try:
        ctx = get_context()
    except NoAdapterError:
        return None
    if traversal == SUBGROUP_TRAVERSAL and traversal_module(ctx) != SUBGROUP_TRAVERSAL:
        return None
    faces = np.arange(3 * len(triangles), dtype=np.uint32).reshape(-1, 3)
    scene = Scene(Camera([0, 0, 3], [0, 0, 0]), [Mesh("m", triangles.reshape(-1, 3), faces, "grey")],
                  {"grey": Material()})
    query = RayQuery(ctx, GeometryBuffers.build(scene).as_variant(layout), traversal=traversal)
    points = triangles.reshape(-1, 3)
    center, radius = points.mean(axis=0), np.ptp(points, axis=0).max()
    rng = np.random.default_rng(1)
    origins = center + rng.normal(0, 1, (rays, 3)) * radius * 2
    targets = center + rng.normal(0, 0.25, (rays, 3)) * radius
    ray_buffer = ctx.upload(query_rays(origins, targets - origins), label="rays")
    outputs = [ctx.storage(rays * HIT_DTYPE.itemsize), ctx.storage(rays * SURFACE_DTYPE.itemsize), None]

    def dispatch():
        encoder = ctx.device.create_command_encoder()
        query.record(encoder, "intersect", ray_buffer, outputs, rays)
        ctx.device.queue.submit([encoder.finish()])
        ctx.read(outputs[0], nbytes=16)        # waits for the GPU

    dispatch()
    seconds, _ = best_of(3, dispatch)
    return rays / seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="10000,100000,1000000")
    parser.add_argument("--no-traversal", action="store_true", help="skip the GPU traversal column")
    args = parser.parse_args()
    cases = [(f"random {int(n):,}", random_soup(int(n))) for n in args.sizes.split(",")]
    if BUNNY.exists():
        import trimesh

        bunny = trimesh.load(BUNNY, force="mesh", process=False)
        cases.append(("stanford bunny", np.asarray(bunny.vertices, np.float32)[bunny.faces]))
    header = (f"{'mesh':>18} {'triangles':>10} {'build s':>8} {'nodes':>9} {'depth':>5} {'mean leaf':>9}"
              + "".join(f" {name + ' Mrays/s':>19}" for name, _, _ in WALKS)
              + f" {'mitsuba s':>9} {'mitsuba/ours':>12}")
    print(header)
    for name, triangles in cases:
        seconds, bvh = best_of(2, lambda: build_bvh(triangles))
        traverse = not args.no_traversal and len(triangles) <= 200_000
        rates = [traversal_rate(triangles, module, layout) if traverse else None for _, module, layout in WALKS]
        peer = mitsuba_load_seconds(triangles)
        walks = "".join(f" {'-' if r is None else f'{r / 1e6:.2f}':>19}" for r in rates)
        mitsuba = f" {'-':>9} {'-':>12}" if peer is None else f" {peer:>9.3f} {f'{peer / seconds:.2f}×':>12}"
        print(f"{name:>18} {len(triangles):>10,} {seconds:>8.3f} {bvh.node_count:>9,} {bvh.depth():>5} "
              f"{bvh.leaf_sizes.mean():>9.2f}{walks}{mitsuba}", flush=True)


if __name__ == "__main__":
    main()
