"""The work each BVH walk does per ray, counted by replaying the walks in Python (no GPU): loop passes,
nodes fetched, box and triangle tests and the bytes read, for the threaded binary walk
(wgsl/accel/walk_tree.wgsl, one invocation alone, the node copy of the ray's octant) and the 4-wide walk
(wgsl/accel/walk_wide.wgsl), the latter also over the tree built with small leaves (the "+small-leaves"
variants, bvh.SMALL_LEAF_TRAVERSAL_COST). What the wide layout and small leaves save in work, independent
of any device, before a GPU says what it is worth in time. Closest-hit rays of two kinds: from a camera through a grid
(coherent) and leaving the mesh's surface in cosine-distributed directions (a path's bounces).

    python3 benchmarks/bench_walk_work.py [--rays 4096] [--mesh bunny|random]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from common import BUNNY, print_header, print_table

from wgpu_rt.accel.bvh import (
    LEAF_COUNT_BITS,
    SMALL_LEAF_TRAVERSAL_COST,
    THREADED_NODE_DTYPE,
    TRAVERSAL_COST,
    WIDE_EMPTY,
    WIDE_LEAF,
    WIDE_NODE_DTYPE,
    build_bvh,
    ordered_threaded_nodes,
    wide_nodes,
)

TRIANGLE_BYTES = 48
LEAF_MASK = (1 << LEAF_COUNT_BITS) - 1


def box_entry(lo, hi, origin, inv_dir, t_max):
    """Where the ray enters the box within (0, t_max), or None (the slab test of walk_tree.wgsl)."""
    near, far = 0.0, t_max
    for k in range(3):
        t0, t1 = (lo[k] - origin[k]) * inv_dir[k], (hi[k] - origin[k]) * inv_dir[k]
        near, far = max(near, min(t0, t1)), min(far, max(t0, t1))
    return near if near <= far and near < t_max else None


def triangle_t(triangle, origin, direction, t_max):
    """The hit distance of the ray on ``triangle`` within (0, t_max), or t_max (Möller–Trumbore)."""
    a, b, c = triangle
    e1 = [b[k] - a[k] for k in range(3)]
    e2 = [c[k] - a[k] for k in range(3)]
    p = [direction[1] * e2[2] - direction[2] * e2[1], direction[2] * e2[0] - direction[0] * e2[2],
         direction[0] * e2[1] - direction[1] * e2[0]]
    det = sum(e1[k] * p[k] for k in range(3))
    if det == 0.0:
        return t_max
    s = [origin[k] - a[k] for k in range(3)]
    u = sum(s[k] * p[k] for k in range(3)) / det
    q = [s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2], s[0] * e1[1] - s[1] * e1[0]]
    v = sum(direction[k] * q[k] for k in range(3)) / det
    t = sum(e2[k] * q[k] for k in range(3)) / det
    return t if u >= 0 and v >= 0 and u + v <= 1 and 0 < t < t_max else t_max


def ray_setup(origin, direction):
    inv = [1.0 / (d if abs(d) > 1e-20 else 1e-20) for d in direction]
    octant = sum(1 << k for k in range(3) if direction[k] < 0)
    return inv, octant


def threaded_walk(copies, node_count, triangles, origin, direction, counts):
    """walk_tree.wgsl's walk of one ray alone; adds its work to ``counts``; returns the hit distance."""
    inv, octant = ray_setup(origin, direction)
    nodes = copies[octant]
    t, index = math.inf, 0
    while index < node_count:
        lo, hi, skip, owned = nodes[index]
        counts["passes"] += 1
        counts["nodes"] += 1
        counts["boxes"] += 1
        counts["bytes"] += THREADED_NODE_DTYPE.itemsize
        if box_entry(lo, hi, origin, inv, t) is None:
            index = skip
            continue
        first = owned >> LEAF_COUNT_BITS
        for prim in range(first, first + (owned & LEAF_MASK)):
            counts["triangles"] += 1
            counts["bytes"] += TRIANGLE_BYTES
            t = triangle_t(triangles[prim], origin, direction, t)
        index += 1
    return t


def wide_walk(nodes, triangles, origin, direction, counts):
    """walk_wide.wgsl's walk of one ray; adds its work to ``counts``; returns the hit distance."""
    inv, _ = ray_setup(origin, direction)
    t, stack, next_ref = math.inf, [], 0
    while True:
        counts["passes"] += 1
        if next_ref >= WIDE_LEAF:
            first = (next_ref & ~WIDE_LEAF) >> LEAF_COUNT_BITS
            for prim in range(first, first + (next_ref & LEAF_MASK)):
                counts["triangles"] += 1
                counts["bytes"] += TRIANGLE_BYTES
                t = triangle_t(triangles[prim], origin, direction, t)
            next_ref = None
        else:
            boxes, refs = nodes[next_ref]
            counts["nodes"] += 1
            counts["boxes"] += 4
            counts["bytes"] += WIDE_NODE_DTYPE.itemsize
            entered = sorted((entry, ref) for (lo, hi), ref in zip(boxes, refs) if ref != WIDE_EMPTY
                             for entry in [box_entry(lo, hi, origin, inv, t)] if entry is not None)
            next_ref = entered[0][1] if entered else None
            stack.extend(reversed(entered[1:]))
        while next_ref is None and stack:   # culled entries leave the stack unfetched
            entry, ref = stack.pop()
            if entry < t:
                next_ref = ref
        if next_ref is None:
            return t


def camera_rays(center, radius, count, rng):
    side = int(math.sqrt(count))
    origin = center + np.array([0.3, 0.4, 2.5]) * radius
    forward = (center - origin) / np.linalg.norm(center - origin)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    s = np.linspace(-0.2, 0.2, side)
    x, y = np.meshgrid(s, s)
    dirs = forward + x.reshape(-1, 1) * right + y.reshape(-1, 1) * up
    return np.repeat(origin[None], len(dirs), 0), dirs / np.linalg.norm(dirs, axis=1, keepdims=True)


def bounce_rays(triangles, count, rng):
    """Rays leaving random surface points (offset along the normal) in cosine-distributed directions."""
    chosen = triangles[rng.integers(0, len(triangles), count)].astype(np.float64)
    weights = rng.dirichlet([1, 1, 1], count)
    points = np.einsum("nk,nkj->nj", weights, chosen)
    normals = np.cross(chosen[:, 1] - chosen[:, 0], chosen[:, 2] - chosen[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-30)
    normals *= rng.choice([-1.0, 1.0], (count, 1))
    local = rng.normal(size=(count, 3))
    local /= np.linalg.norm(local, axis=1, keepdims=True)
    dirs = local + normals                  # cosine-distributed about the normal
    dirs /= np.maximum(np.linalg.norm(dirs, axis=1, keepdims=True), 1e-30)
    scale = np.abs(points).max(axis=1, keepdims=True).clip(1.0)
    return points + normals * 1e-5 * scale, dirs


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rays", type=int, default=4096, help="rays of each kind")
    parser.add_argument("--mesh", choices=["bunny", "random"], default="bunny")
    args = parser.parse_args()
    print_header(args)
    rng = np.random.default_rng(0)
    if args.mesh == "bunny":
        if not BUNNY.exists():
            print(f"skipped: {BUNNY} not found")
            return 0
        import trimesh

        mesh = trimesh.load(BUNNY, force="mesh", process=False)
        triangles = np.asarray(mesh.vertices, np.float32)[mesh.faces]
    else:
        triangles = (rng.uniform(-1, 1, (100_000, 1, 3)) + rng.normal(0, 0.02, (100_000, 3, 3))).astype(np.float32)
    trees, build_seconds = {}, {}
    for name, cost in (("default", TRAVERSAL_COST), ("small leaves", SMALL_LEAF_TRAVERSAL_COST)):
        started = time.perf_counter()
        trees[name] = build_bvh(triangles, cost)
        build_seconds[name] = time.perf_counter() - started
    print_table(f"the two trees of {len(triangles):,} triangles", ["tree", "node visit cost", "binary nodes",
                "wide nodes", "triangles a leaf", "build s"],
                [[name, cost, tree.node_count, len(wide_nodes(tree)), tree.leaf_sizes.mean(), build_seconds[name]]
                 for (name, tree), cost in zip(trees.items(), (TRAVERSAL_COST, SMALL_LEAF_TRAVERSAL_COST))])
    bvh = trees["default"]
    ordered = triangles[bvh.order].astype(np.float64).tolist()
    copies = ordered_threaded_nodes(bvh)
    count = bvh.node_count
    threaded = [[(tuple(n["lo"]), tuple(n["hi"]), int(n["skip"]), int(n["triangles"]))
                 for n in copies[k * count:(k + 1) * count]] for k in range(8)]

    def wide_tree(tree):
        return ([(list(zip(node["lo"].T.tolist(), node["hi"].T.tolist())), node["children"].tolist())
                 for node in wide_nodes(tree)], triangles[tree.order].astype(np.float64).tolist())

    wide_trees = {"wide": wide_tree(bvh), "wide, small leaves": wide_tree(trees["small leaves"])}
    points = triangles.reshape(-1, 3).astype(np.float64)
    center, radius = points.mean(axis=0), np.ptp(points, axis=0).max()
    rows = []
    for kind, (origins, dirs) in (("camera", camera_rays(center, radius, args.rays, rng)),
                                  ("bounce", bounce_rays(triangles, args.rays, rng))):
        work = {}
        for walk in ("threaded", *wide_trees):
            counts = dict.fromkeys(("passes", "nodes", "boxes", "triangles", "bytes"), 0)
            hits = []
            for origin, direction in zip(origins.tolist(), dirs.tolist()):
                hits.append(threaded_walk(threaded, count, ordered, origin, direction, counts) if walk == "threaded"
                            else wide_walk(*wide_trees[walk], origin, direction, counts))
            work[walk] = ({k: v / len(origins) for k, v in counts.items()}, np.array(hits))
        for walk in wide_trees:
            assert np.array_equal(work["threaded"][1], work[walk][1]), f"the {walk} walk found different hits"
        for walk, (per_ray, _) in work.items():
            rows.append([kind, walk, per_ray["passes"], per_ray["nodes"], per_ray["boxes"], per_ray["triangles"],
                         per_ray["bytes"] / 1024])
    print_table(f"work per closest-hit ray, {args.mesh} ({len(triangles):,} triangles), {args.rays} rays of each kind",
                ["rays", "walk", "loop passes", "nodes fetched", "box tests", "triangle tests", "KiB read"], rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
