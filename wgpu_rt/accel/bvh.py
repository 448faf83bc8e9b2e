"""Binned SAH BVH over triangles, built level by level with vectorized numpy.

Every level of the tree is processed at once: the triangles of all nodes still to split are gathered,
binned along each axis (``BINS`` bins over the centroid bounds, bin bounds via ``np.minimum.at``), and
the surface area heuristic picks, per node, the cheapest axis and bin boundary (or a leaf, when the SAH
says a leaf is cheaper and it holds at most ``MAX_LEAF_SIZE`` triangles). Triangles are partitioned
stably in place with cumulative sums, so the cost per level is O(triangles) with no Python loop over
nodes or triangles. Nodes whose centroids all coincide (duplicates, degenerate input) are split at the
middle of their range; nodes at depth ``MAX_DEPTH`` become leaves, which bounds the number of levels.

Flattened layout, 32 bytes per node (``NODE_DTYPE``), root at 0, the two children of a node adjacent:
``lo`` (3 × f32), ``first`` (u32), ``hi`` (3 × f32), ``count`` (u32). ``count == 0`` marks an interior
node whose children are ``first`` and ``first + 1``; otherwise the node is a leaf over triangles
``first .. first + count`` of the reordered triangle list (``Bvh.order`` maps them to input indices).
Triangles with zero area (collinear or repeated vertices, tested exactly: ``zero_area``) are in no leaf:
they come last in ``order``, so they keep their attributes but the GPU never tests them. Its watertight
test gives a repeated vertex an exactly zero edge function, but it rounds vertices into ray space, which
can give three collinear ones a sliver of area that a ray through their line hits. With no triangle of
non-zero area, the root is a leaf with a box at +inf that no ray enters.

The GPU walks the tree without a stack, so ``threaded_nodes`` re-lays it out in depth-first order
(``THREADED_NODE_DTYPE``, also 32 bytes): a node's first child follows it, and ``skip`` is the index
just past its subtree, where the walk goes when the node's box is missed; interior nodes also carry
one triangle lifted from a leaf below (see its docstring).
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np

BINS = 16
MAX_LEAF_SIZE = 15        # the most LEAF_COUNT_BITS can hold
MAX_DEPTH = 32
# One node visit relative to one ray/triangle test, as the GPU walk pays them on lavapipe: a visit
# fetches the node, tests two boxes for a whole subgroup packet and goes round the triangle loop at
# least once, so it costs several triangle tests (measured: 8 with leaves up to 15 beat 2 with leaves
# up to 8 by ~11% in samples/s on cornell and sun-room, and tied on the bunny and mesh scenes).
TRAVERSAL_COST = 8.0
# The same for trees built with small leaves (the "+small-leaves" variants of the wide layouts, for
# walks in which each invocation tests its own triangles, as GPUs run them): a node visit costing two
# triangle tests. On the bunny that cuts the triangles a bouncing ray tests in the 4-wide walk from 29 to 8
# for a fifth more node visits and a quarter fewer bytes read (benchmarks/bench_walk_work.py,
# BENCHMARKS.md §24); whether that is faster is the adapter's to say (wgpu_rt.trace.bvh_choice).
SMALL_LEAF_TRAVERSAL_COST = 2.0
NODE_DTYPE = np.dtype([("lo", "<f4", 3), ("first", "<u4"), ("hi", "<f4", 3), ("count", "<u4")])
LEAF_COUNT_BITS = 4       # a threaded node packs its triangles as (first << LEAF_COUNT_BITS) | count
THREADED_NODE_DTYPE = np.dtype([("lo", "<f4", 3), ("skip", "<u4"), ("hi", "<f4", 3), ("triangles", "<u4")])
assert MAX_LEAF_SIZE < 1 << LEAF_COUNT_BITS
ORDERINGS = 8             # ordered_threaded_nodes: one child order per direction octant


@dataclass
class Bvh:
    nodes: np.ndarray       # (M,) NODE_DTYPE
    order: np.ndarray       # (T,) input triangle index of each leaf slot

    @property
    def node_count(self) -> int:
        return len(self.nodes)

    @property
    def leaf_sizes(self) -> np.ndarray:
        return self.nodes["count"][self.nodes["count"] > 0]

    def depth(self) -> int:
        """Number of levels from the root to the deepest leaf (a single leaf has depth 1)."""
        level, depth = np.array([0]), 0
        while len(level):
            depth += 1
            interior = level[self.nodes["count"][level] == 0]
            first = self.nodes["first"][interior].astype(np.int64)
            level = np.concatenate([first, first + 1])
        return depth


def _surface_area(lo: np.ndarray, hi: np.ndarray, axis: int = -1) -> np.ndarray:
    """Surface areas of boxes whose x, y, z run along ``axis`` (empty boxes, lo > hi, give 0)."""
    x, y, z = np.moveaxis(np.maximum(hi - lo, 0.0), axis, 0)
    return 2.0 * (x * y + y * z + z * x)


def _segment_index(starts: np.ndarray, counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For segments [start, start + count): every position, and which segment it belongs to."""
    segment = np.repeat(np.arange(len(counts)), counts)
    offsets = np.cumsum(counts) - counts
    return starts[segment] + (np.arange(int(counts.sum())) - offsets[segment]), segment


def bin_counts(traversal_cost: float) -> tuple:
    """Bins per node by triangle count: (more than, at most, bins). Small nodes need few bins, and most
    nodes are small, so this keeps the per-level tables near the triangle count in size. Nodes with at most
    ``traversal_cost`` triangles are never binned: no split can beat their leaf cost."""
    return ((32, np.iinfo(np.int64).max, BINS), (8, 32, 8), (int(traversal_cost), 8, 4))


def _running(op, bins: np.ndarray, reverse: bool = False) -> np.ndarray:
    """``op`` (np.minimum or np.maximum) run along axis 1 of (3, bins, nodes) tables, from the last bin
    down with ``reverse``: one vector operation per bin, where ``op.accumulate`` along that axis took
    30–70× the time."""
    out, step = bins.copy(), 1 if reverse else -1   # bin b takes op(bin b, its neighbour b + step)
    for b in (range(bins.shape[1] - 2, -1, -1) if reverse else range(1, bins.shape[1])):
        op(out[:, b + step], out[:, b], out=out[:, b])
    return out


MIN_BIN_EXTENT = 1e-30   # centroids spread over less than this along an axis all fall in one bin of it


def _sah_costs(bounds, segment, counts, c_lo, c_hi, bins):
    """SAH cost (3, bins - 1, nodes) of every bin boundary of every axis, and each triangle's bin
    (n, 3). ``bounds`` is (9, n): lo, hi and centroid rows of the nodes' triangles. Tables are
    bins-major so the prefix scans run as ``bins`` vector operations."""
    nodes_here = len(counts)
    extent = c_hi - c_lo
    spread = extent > MIN_BIN_EXTENT      # (narrower, bins / extent would overflow float32: one bin)
    bin_scale = np.where(spread, bins * (1 - 1e-6) / np.where(spread, extent, 1), 0.0).astype(np.float32)
    prim_bins = ((bounds[6:9] - np.take(c_lo.T, segment, axis=1))
                 * np.take(bin_scale.T, segment, axis=1)).astype(np.int32)
    np.clip(prim_bins, 0, bins - 1, out=prim_bins)
    costs = np.empty((3, bins - 1, nodes_here), np.float32)
    prim_lo, prim_hi = bounds[0:3], bounds[3:6]
    for axis in range(3):
        key = prim_bins[axis] * nodes_here + segment
        bin_count = np.bincount(key, minlength=nodes_here * bins).reshape(bins, nodes_here)
        bin_lo = np.full((3, bins * nodes_here), np.inf, np.float32)
        bin_hi = np.full((3, bins * nodes_here), -np.inf, np.float32)
        for component in range(3):   # 1-D ufunc.at takes numpy's fast path
            np.minimum.at(bin_lo[component], key, prim_lo[component])
            np.maximum.at(bin_hi[component], key, prim_hi[component])
        bin_lo, bin_hi = bin_lo.reshape(3, bins, nodes_here), bin_hi.reshape(3, bins, nodes_here)
        n_left = np.cumsum(bin_count, axis=0)[:-1]
        n_right = counts[None, :] - n_left
        area_left = _surface_area(_running(np.minimum, bin_lo), _running(np.maximum, bin_hi), 0)[:-1]
        area_right = _surface_area(_running(np.minimum, bin_lo, reverse=True),
                                   _running(np.maximum, bin_hi, reverse=True), 0)[1:]
        cost = area_left * n_left + area_right * n_right      # empty sides give 0 · 0
        costs[axis] = np.where((n_left > 0) & (n_right > 0), cost, np.inf)
    return costs, prim_bins


def build_bvh(triangles: np.ndarray, traversal_cost: float = TRAVERSAL_COST) -> Bvh:
    """The BVH of ``triangles`` (T, 3, 3) float32 world-space vertices (T ≥ 1), split while the SAH with
    a node visit costing ``traversal_cost`` triangle tests says a split is cheaper than a leaf."""
    triangles = np.asarray(triangles, np.float32)
    if len(triangles) == 0:
        raise ValueError("cannot build a BVH over zero triangles")
    flat = zero_area(triangles)
    order = np.concatenate([np.flatnonzero(~flat), np.flatnonzero(flat)])   # leaves hold the first `count`
    count = int(np.count_nonzero(~flat))
    if count == 0:
        root = np.zeros(1, NODE_DTYPE)
        root["lo"], root["hi"], root["count"] = np.inf, np.inf, 1
        return Bvh(root, order)
    return _build(triangles.min(axis=1), triangles.max(axis=1), order, count, MAX_LEAF_SIZE, traversal_cost)


def build_box_bvh(lo: np.ndarray, hi: np.ndarray) -> Bvh:
    """A BVH over boxes (N ≥ 1, each (3,) ``lo`` ≤ ``hi``) with one box per leaf: the top level of a
    two-level scene, whose boxes are its instances' world bounds."""
    lo, hi = np.asarray(lo, np.float32), np.asarray(hi, np.float32)
    return _build(lo, hi, np.arange(len(lo)), len(lo), 1)


def _build(tri_lo: np.ndarray, tri_hi: np.ndarray, order: np.ndarray, count: int, max_leaf_size: int,
           traversal_cost: float = TRAVERSAL_COST) -> Bvh:
    """build_bvh over the bounds of items ``order[:count]``, leaves of at most ``max_leaf_size``."""
    # Per item lo, hi, centroid as rows, kept in the order of ``order`` (partitioned with it): each level
    # reads its nodes' ranges nearly in sequence instead of gathering items from all over.
    ordered_bounds = np.take(np.concatenate([tri_lo.T, tri_hi.T, ((tri_lo + tri_hi) * 0.5).T]), order, axis=1)
    capacity = 2 * count
    node_lo = np.zeros((capacity, 3), np.float32)
    node_hi = np.zeros((capacity, 3), np.float32)
    node_first = np.zeros(capacity, np.int64)
    node_count = np.zeros(capacity, np.int64)
    # Nodes still to process: their triangle range in ``order`` and their node index.
    starts, counts, nodes = np.array([0]), np.array([count]), np.array([0])
    node_total, depth = 1, 0
    while len(nodes):
        positions, segment = _segment_index(starts, counts)
        prims = np.take(order, positions)
        bounds = np.take(ordered_bounds, positions, axis=1)   # np.take: ~4× the speed of fancy indexing
        offsets = np.cumsum(counts) - counts
        lo = np.minimum.reduceat(bounds[0:3], offsets, axis=1).T
        hi = np.maximum.reduceat(bounds[3:6], offsets, axis=1).T
        node_lo[nodes], node_hi[nodes] = lo, hi
        c_lo = np.minimum.reduceat(bounds[6:9], offsets, axis=1).T
        c_hi = np.maximum.reduceat(bounds[6:9], offsets, axis=1).T

        nodes_here = len(nodes)
        best_cost = np.full(nodes_here, np.inf)
        best_axis = np.zeros(nodes_here, np.int64)
        best_split = np.zeros(nodes_here, np.int64)       # triangles in bins >= best_split go right
        prim_bin = np.zeros(len(prims), np.int64)          # each triangle's bin along its node's best axis
        for above, at_most, bins in bin_counts(traversal_cost):
            group = (counts > above) & (counts <= at_most)
            if not np.any(group):
                continue
            in_group = group[segment]
            local_segment = (np.cumsum(group) - 1)[segment[in_group]]
            group_bounds = bounds if len(local_segment) == len(segment) else np.compress(in_group, bounds, axis=1)
            costs, chosen_bins = _sah_costs(group_bounds, local_segment, counts[group], c_lo[group], c_hi[group],
                                            bins)
            flat = costs.reshape(-1, int(group.sum()))
            best = np.argmin(flat, axis=0)
            best_cost[group] = flat[best, np.arange(flat.shape[1])]
            best_axis[group], best_split[group] = best // (bins - 1), best % (bins - 1) + 1
            prim_bin[in_group] = chosen_bins[best_axis[group][local_segment], np.arange(len(local_segment))]
        node_area = _surface_area(lo.astype(np.float64), hi.astype(np.float64))
        split_cost = traversal_cost + best_cost / np.where(node_area > 0, node_area, 1.0)
        has_split = np.isfinite(best_cost)
        must_split = counts > max_leaf_size
        split = (must_split | (has_split & (split_cost < counts))) & (counts > 1) & (depth < MAX_DEPTH - 1)
        median = split & ~has_split

        leaves = ~split
        node_first[nodes[leaves]], node_count[nodes[leaves]] = starts[leaves], counts[leaves]
        if not np.any(split):
            break
        # Stable partition of each splitting node's range: left side first.
        in_split = split[segment]
        local = positions - starts[segment]
        goes_right = np.where(median[segment], local >= counts[segment] // 2,
                              prim_bin >= best_split[segment])
        goes_right, seg, pos, prim = goes_right[in_split], segment[in_split], positions[in_split], prims[in_split]
        right_before = np.cumsum(goes_right) - goes_right
        split_counts = np.where(split, counts, 0)
        first_of_segment = (np.cumsum(split_counts) - split_counts)[seg]   # where seg's range starts here
        right_rank = right_before - right_before[first_of_segment]
        left_rank = (pos - starts[seg]) - right_rank
        n_left_all = np.bincount(seg, weights=~goes_right, minlength=nodes_here).astype(np.int64)
        placed = np.where(goes_right, starts[seg] + n_left_all[seg] + right_rank, starts[seg] + left_rank)
        order[placed] = prim
        ordered_bounds[:, placed] = np.compress(in_split, bounds, axis=1)

        parents = nodes[split]
        children = node_total + 2 * np.arange(len(parents))
        node_first[parents], node_count[parents] = children, 0
        node_total += 2 * len(parents)
        n_left = n_left_all[split]
        starts = np.concatenate([starts[split], starts[split] + n_left])
        counts = np.concatenate([n_left, counts[split] - n_left])
        nodes = np.concatenate([children, children + 1])
        depth += 1

    packed = np.zeros(node_total, NODE_DTYPE)
    packed["lo"], packed["hi"] = node_lo[:node_total], node_hi[:node_total]
    packed["first"], packed["count"] = node_first[:node_total], node_count[:node_total]
    return Bvh(packed, order)


def zero_area(triangles: np.ndarray) -> np.ndarray:
    """Per triangle of ``triangles`` (T, 3, 3) float32: are its vertices collinear, exactly? Two equal
    vertices make it so. Otherwise each component of the cross product of two edges, a difference of
    two products computed in float64, is within a few ulps of the products' magnitudes of the exact
    one (edges of float32 vertices neither underflow nor overflow in float64), so one beyond 16 such
    ulps is not zero; the few triangles left are decided in exact rational arithmetic."""
    vertices = np.asarray(triangles, np.float64)
    repeated = np.any(np.all(vertices[:, [0, 0, 1]] == vertices[:, [1, 2, 2]], axis=2), axis=1)
    e1, e2 = vertices[:, 1] - vertices[:, 0], vertices[:, 2] - vertices[:, 0]
    magnitude = np.abs(e1[:, [1, 2, 0]] * e2[:, [2, 0, 1]]) + np.abs(e1[:, [2, 0, 1]] * e2[:, [1, 2, 0]])
    flat = np.all(np.abs(np.cross(e1, e2)) <= 16 * np.finfo(np.float64).eps * magnitude, axis=1)
    for index in np.flatnonzero(flat & ~repeated):
        a, b, c = ([Fraction(float(x)) for x in vertex] for vertex in vertices[index])
        u, v = [q - p for p, q in zip(a, b)], [q - p for p, q in zip(a, c)]
        flat[index] = u[1] * v[2] == u[2] * v[1] and u[2] * v[0] == u[0] * v[2] and u[0] * v[1] == u[1] * v[0]
    return flat


def threaded_nodes(bvh: Bvh, octant: int | None = None) -> np.ndarray:
    """The nodes in depth-first order as THREADED_NODE_DTYPE, for a stackless walk (each node's left
    child first, or with ``octant``, the child that rays of that octant meet first; see
    ordered_threaded_nodes):
    entering a node moves to the next one (its first child, or past a leaf), missing it moves to
    ``skip``, the index after its subtree (the node count for the last subtree).

    Every node may own triangles, ``triangles = (first << LEAF_COUNT_BITS) | count``: a leaf its
    range, and an interior node one triangle lifted off the end of a leaf below it that holds at least
    two. A walk tests a node's triangles when it enters the node; a lifted triangle lies inside every
    box above its leaf, so every ray that needs it still tests it. Why lift: on SIMD drivers the
    per-node triangle loop runs at least once even where it has nothing to do, so an interior node
    can test one triangle for free. Computed level by level: lifting and subtree sizes bottom-up
    (each subtree offers its fullest leaf to its parent), then depth-first positions top-down."""
    return _lay_out(bvh, _thread(bvh), octant)


def _thread(bvh: Bvh) -> tuple:
    """What threaded_nodes computes whatever the child order: per level, its splits (interior nodes,
    left children, child centre offsets), and per node its triangles word and its subtree's size."""
    nodes = bvh.nodes
    count = len(nodes)
    if len(bvh.order) >= 1 << (32 - LEAF_COUNT_BITS):
        raise ValueError(f"{len(bvh.order)} triangles do not fit the threaded node layout")
    levels, level = [], np.array([0])
    while len(level):
        levels.append(level)
        interior = level[nodes["count"][level] == 0]
        left = nodes["first"][interior].astype(np.int64)
        level = np.concatenate([left, left + 1])
    is_leaf = nodes["count"] > 0
    first = np.where(is_leaf, nodes["first"], 0).astype(np.int64)
    owned = nodes["count"].astype(np.int64)       # triangles each node tests (interior: 0 or 1)
    donor = np.where(is_leaf, np.arange(count), -1)   # per subtree: its leaf with the most triangles
    size = np.ones(count, np.int64)
    for level in reversed(levels):
        interior = level[~is_leaf[level]]
        left = nodes["first"][interior].astype(np.int64)
        size[interior] = 1 + size[left] + size[left + 1]
        candidates = np.stack([donor[left], donor[left + 1]])
        offered = np.where(candidates >= 0, owned[np.maximum(candidates, 0)], 0)
        best = candidates[np.argmax(offered, axis=0), np.arange(len(interior))]
        lifts = np.max(offered, axis=0) >= 2
        leaf, taker = best[lifts], interior[lifts]
        owned[leaf] -= 1
        first[taker], owned[taker] = first[leaf] + owned[leaf], 1
        still = np.where(candidates >= 0, owned[np.maximum(candidates, 0)], 0)
        donor[interior] = candidates[np.argmax(still, axis=0), np.arange(len(interior))]
    splits = []   # per level: its interior nodes, their left children, right centre − left centre
    for level in levels:
        interior = level[~is_leaf[level]]
        left = nodes["first"][interior].astype(np.int64)
        splits.append((interior, left, _centers(nodes, left + 1) - _centers(nodes, left)))
    return splits, (first << LEAF_COUNT_BITS) | owned, size


def _lay_out(bvh: Bvh, threading: tuple, octant: int | None) -> np.ndarray:
    """threaded_nodes' top-down part: depth-first positions in ``octant``'s child order."""
    splits, triangles, size = threading
    position = np.zeros(len(bvh.nodes), np.int64)
    signs = np.where([octant >> axis & 1 for axis in range(3)], -1.0, 1.0) if octant is not None else None
    for interior, near, offset in splits:
        far = near + 1
        if signs is not None:
            right_first = offset @ signs < 0
            near, far = np.where(right_first, far, near), np.where(right_first, near, far)
        position[near] = position[interior] + 1
        position[far] = position[interior] + 1 + size[near]
    threaded = np.zeros(len(bvh.nodes), THREADED_NODE_DTYPE)
    threaded["lo"][position], threaded["hi"][position] = bvh.nodes["lo"], bvh.nodes["hi"]
    threaded["skip"][position] = position + size
    threaded["triangles"][position] = triangles
    return threaded


def _centers(nodes: np.ndarray, index: np.ndarray) -> np.ndarray:
    return 0.5 * (nodes["lo"][index].astype(np.float64) + nodes["hi"][index].astype(np.float64))


def ordered_threaded_nodes(bvh: Bvh, orderings: int = ORDERINGS) -> np.ndarray:
    """threaded_nodes for each of the ORDERINGS direction octants (octant bit k set: the direction's
    component k is negative), one copy after another, skips relative to the copy's start. A ray walks
    the copy of its octant (a subgroup packet: that of its summed direction) and so visits the child
    nearer along its direction first: its closest hit so far is short sooner and culls more boxes,
    which a single fixed order cannot do for every direction without a stack. ``orderings`` = 1 keeps
    only octant 0's copy (for scenes whose copies would not all fit a storage binding)."""
    threading = _thread(bvh)
    return np.concatenate([_lay_out(bvh, threading, octant) for octant in range(orderings)])


# The 4-wide layout (wide_nodes), 112 bytes a node: the boxes of its four children as six rows of four
# (lo x, lo y, lo z, hi x, hi y, hi z; child k in column k), then the four child references: a wide
# node's index, or WIDE_LEAF | (first << LEAF_COUNT_BITS) | count for a leaf's triangles, or WIDE_EMPTY.
WIDTH = 4
WIDE_NODE_DTYPE = np.dtype([("lo", "<f4", (3, WIDTH)), ("hi", "<f4", (3, WIDTH)), ("children", "<u4", WIDTH)])
WIDE_LEAF = 1 << 31
WIDE_EMPTY = 0xFFFFFFFF
# The walk's stack (wgsl/accel/walk_wide.wgsl) holds at most WIDTH - 1 references per level it has
# descended, and a wide tree is no deeper than the binary one it collapses (MAX_DEPTH levels).
WIDE_STACK_SIZE = (WIDTH - 1) * MAX_DEPTH


def wide_nodes(bvh: Bvh) -> np.ndarray:
    """The binary ``bvh`` collapsed into a 4-wide tree as WIDE_NODE_DTYPE, root at 0, for a walk with a
    stack that visits the children a ray enters nearest first (wgsl/accel/walk_wide.wgsl): a quarter of
    the binary tree's nodes, each fetched once for four box tests. Each wide node starts from a binary
    interior node's two children and, twice, opens the interior one with the largest surface area (the
    one rays enter most often) into its own two children; interior children become the next level's
    wide nodes. Leaves are the binary tree's. Level by level, vectorized over the level's nodes."""
    nodes = bvh.nodes
    if len(bvh.order) >= 1 << (31 - LEAF_COUNT_BITS):
        raise ValueError(f"{len(bvh.order)} triangles do not fit the wide node layout")
    count = nodes["count"].astype(np.int64)
    left = nodes["first"].astype(np.int64)
    interior = count == 0
    if not interior[0]:   # a root leaf (a few triangles, or none with area: then its box is at +inf)
        levels = [np.array([[0, -1, -1, -1]])]
    else:
        area = _surface_area(nodes["lo"].astype(np.float64), nodes["hi"].astype(np.float64))
        levels, level = [], np.array([0])
        while len(level):
            slots = np.full((len(level), WIDTH), -1, np.int64)
            slots[:, 0], slots[:, 1] = left[level], left[level] + 1
            rows = np.arange(len(level))
            for free in range(2, WIDTH):
                opens = np.where((slots >= 0) & interior[np.maximum(slots, 0)], area[np.maximum(slots, 0)], -1.0)
                pick = np.argmax(opens, axis=1)
                chosen = slots[rows, pick]
                ok = opens[rows, pick] >= 0
                slots[ok, free] = left[chosen[ok]] + 1
                slots[ok, pick[ok]] = left[chosen[ok]]
            levels.append(slots)
            level = slots[(slots >= 0) & interior[np.maximum(slots, 0)]]
    if len(levels) > MAX_DEPTH:
        raise ValueError(f"a wide tree of {len(levels)} levels overflows the walk's stack")
    slots = np.concatenate(levels)
    valid = slots >= 0
    safe = np.maximum(slots, 0)
    opens_node = valid & interior[safe]
    # Wide nodes are numbered level by level in the order their binary nodes appear in `slots`, so an
    # interior child's number is the root's 1 plus its rank among the interior children before it.
    wide_index = np.cumsum(opens_node.ravel()).reshape(slots.shape)
    leaf_ref = WIDE_LEAF | (left[safe] << LEAF_COUNT_BITS) | count[safe]
    wide = np.zeros(len(slots), WIDE_NODE_DTYPE)
    wide["children"] = np.where(valid, np.where(opens_node, wide_index, leaf_ref), WIDE_EMPTY).astype(np.uint32)
    wide["lo"] = np.where(valid[:, None, :], np.transpose(nodes["lo"][safe], (0, 2, 1)), np.inf)
    wide["hi"] = np.where(valid[:, None, :], np.transpose(nodes["hi"][safe], (0, 2, 1)), np.inf)
    return wide


# The 4-wide layout with its child boxes quantized to 8 bits a coordinate ("wide8"), 64 bytes a node
# instead of 112: row 0 the origin (the union of the children's boxes' low corner, f32 x, y, z) and the
# three axes' biased f32 exponents of the grid step (bytes 0, 1, 2 of word 3); rows 1 and 2 the
# children's quantized lo x, lo y, lo z, hi x, hi y, hi z (one word each, child k in byte k), then the
# four child references as in WIDE_NODE_DTYPE; two words of padding. The GPU decodes a coordinate as
# origin + q · 2^e in f32 (wgsl/accel/wide_node_quantized.wgsl), one rounding, which contains the child's
# box by construction (quantized_wide_nodes).
QUANTIZED_WIDE_NODE_WORDS = 16
QUANTIZED_GRID = 254   # steps across the union's extent: the top step (255) is headroom for rounding


def _decoded(origin, quantized, step) -> np.ndarray:
    """Grid coordinates back to f32 as the GPU decodes them: q · step is exact (8 bits times a power of
    two), so origin + q · step rounds once."""
    return np.asarray(origin, np.float32) + np.asarray(quantized * step, np.float32)


def dequantized_boxes(words: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 16) quantized wide node words → their children's (N, 3, 4) lo and hi boxes, decoded in f32
    exactly as the GPU does (origin + q · 2^e, one rounding: q · 2^e is exact)."""
    words = np.asarray(words, np.uint32)
    origin = words[:, :3].view(np.float32)                                            # (N, 3)
    exponents = (words[:, 3:4] >> np.array([0, 8, 16], np.uint32)) & np.uint32(255)   # (N, 3)
    step = (exponents << np.uint32(23)).view(np.float32)
    quantized = ((words[:, 4:10, None] >> np.array([0, 8, 16, 24], np.uint32)) & np.uint32(255)).astype(np.float32)
    decoded = _decoded(origin[:, [0, 1, 2, 0, 1, 2], None], quantized, step[:, [0, 1, 2, 0, 1, 2], None])   # (N, 6, 4)
    return decoded[:, :3], decoded[:, 3:]


def quantized_wide_nodes(wide: np.ndarray) -> np.ndarray:
    """``wide`` (WIDE_NODE_DTYPE) as (N, QUANTIZED_WIDE_NODE_WORDS) u32 words, each child's box on a grid of
    QUANTIZED_GRID steps over the union of its node's child boxes, lo rounded down and hi up, then moved
    a step further wherever the f32 decoding would not contain the box. A step is never below the f32
    spacing at the node's coordinates, so the last one always reaches past the union. Empty slots decode
    to an inverted box (the walk skips them by their reference); a node whose boxes are not finite (the
    root of a tree of no triangle with area) decodes to boxes at +inf, which no ray enters."""
    lo, hi = wide["lo"].astype(np.float64), wide["hi"].astype(np.float64)            # (N, 3, 4)
    valid = (wide["children"] != WIDE_EMPTY)[:, None, :]                              # (N, 1, 4)
    union_lo = np.where(valid, lo, np.inf).min(axis=2)                                # (N, 3)
    union_hi = np.where(valid, hi, -np.inf).max(axis=2)
    finite = np.all(np.isfinite(union_lo) & np.isfinite(union_hi), axis=1)           # (N,)
    union_lo = np.where(finite[:, None], union_lo, 0.0).astype(np.float32)           # the origin, exact in f32
    union_hi = np.where(finite[:, None], union_hi, 0.0)
    magnitude = np.maximum(np.abs(union_lo.astype(np.float64)), np.abs(union_hi))
    spacing = np.floor(np.log2(np.maximum(magnitude, 2.0 ** -100))) - 23             # f32's step there
    wanted = np.ceil(np.log2(np.maximum((union_hi - union_lo) / QUANTIZED_GRID, 2.0 ** -126)))
    exponent = np.clip(np.maximum(wanted, spacing), -126, 127).astype(np.int64)      # (N, 3)
    step = np.ldexp(1.0, exponent)[:, :, None]
    origin = union_lo.astype(np.float64)[:, :, None]
    q_lo = np.clip(np.floor((lo - origin) / step), 0, 255)
    q_hi = np.clip(np.ceil((hi - origin) / step), 0, 255)
    for _ in range(2):   # one rounding can put a decoded corner just inside the box: a step further out
        q_lo = np.where((_decoded(origin, q_lo, step) > lo.astype(np.float32)) & (q_lo > 0), q_lo - 1, q_lo)
        q_hi = np.where((_decoded(origin, q_hi, step) < hi.astype(np.float32)) & (q_hi < 255), q_hi + 1, q_hi)
    q_lo = np.where(valid, q_lo, 255).astype(np.uint32)
    q_hi = np.where(valid, q_hi, 0).astype(np.uint32)
    words = np.zeros((len(wide), QUANTIZED_WIDE_NODE_WORDS), np.uint32)
    words[:, :3] = np.where(finite[:, None], union_lo, np.float32(np.inf)).view(np.uint32)
    biased = np.where(finite[:, None], exponent + 127, 127).astype(np.uint32)
    words[:, 3] = biased[:, 0] | biased[:, 1] << 8 | biased[:, 2] << 16
    packed = np.concatenate([q_lo, q_hi], axis=1)                                     # (N, 6, 4)
    words[:, 4:10] = packed[:, :, 0] | packed[:, :, 1] << 8 | packed[:, :, 2] << 16 | packed[:, :, 3] << 24
    words[:, 10:14] = wide["children"]
    return words
