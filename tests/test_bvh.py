"""BVH build and GPU traversal (wgsl/accel/bvh.wgsl through wgsl/accel/ray_query.wgsl) against brute force.

The reference intersects every ray with every triangle in float64. Rays whose answer is numerically
ambiguous (the nearest hit within 1e-4 of a triangle edge, or two hits within 1e-4 in t) may go
either way in f32, so agreement is required on all other rays and at least 90% of rays must be
unambiguous, which keeps the check meaningful.
"""

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wgpu_rt.accel import bvh as bvh_module
from wgpu_rt.accel.bvh import (
    LEAF_COUNT_BITS,
    MAX_DEPTH,
    MAX_LEAF_SIZE,
    SMALL_LEAF_TRAVERSAL_COST,
    WIDE_EMPTY,
    WIDE_LEAF,
    WIDE_STACK_SIZE,
    WIDTH,
    build_box_bvh,
    build_bvh,
    dequantized_boxes,
    quantized_wide_nodes,
    threaded_nodes,
    wide_nodes,
    zero_area,
)
from wgpu_rt.accel.geometry import LANES_TRAVERSAL, GeometryBuffers, compose_with_traversal
from wgpu_rt.scene.model import Camera, Material, Mesh, Scene
from wgpu_rt.accel.ray_query import NO_HIT, RayQuery, query_rays
from wgpu_rt.shaders import compose, read_wgsl

BUNNY = Path(__file__).resolve().parents[1].parent / "shared" / "meshes" / "stanford-bunny.obj"
EDGE_MARGIN = 1e-4
# GeometryBuffers' variants (accel.geometry.bvh_variants): each node layout with its walk, and each
# fetched as rows by the per-invocation traversal (the only one rows are chosen beside); the wide layouts
# also over a BVH built with small leaves
LAYOUTS = ("threaded", "wide", "wide8", "threaded+rows", "wide+rows", "wide8+rows", "wide+small-leaves",
           "wide8+small-leaves+rows")


def variant_geometry(scene, variant: str, frame: int = 0) -> GeometryBuffers:
    return GeometryBuffers.build(scene, frame).as_variant(variant)


def traversal_for(geometry) -> str | None:
    """Row loads run beside the per-invocation traversal; the rest with the adapter's own."""
    return LANES_TRAVERSAL if geometry.row_loads else None


def query_for(gpu, geometry) -> RayQuery:
    return RayQuery(gpu, geometry, traversal=traversal_for(geometry))


def brute_force(triangles, origins, dirs, t_max=np.inf):
    """Per ray: (nearest t, its triangle or -1, ambiguous flag) over all triangles of non-zero area
    (``triangles`` float32), in float64."""
    tri = np.asarray(triangles, np.float64)
    o = np.asarray(origins, np.float64)[:, None]
    d = np.asarray(dirs, np.float64)[:, None]
    e1, e2 = tri[None, :, 1] - tri[None, :, 0], tri[None, :, 2] - tri[None, :, 0]
    p = np.cross(d, e2)
    det = np.sum(e1 * p, axis=-1)
    ok = np.abs(det) > 1e-12 * np.linalg.norm(np.cross(e1, e2), axis=-1).clip(1e-300) * np.linalg.norm(d, axis=-1)
    ok &= ~zero_area(triangles)[None]
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = o - tri[None, :, 0]
    u = np.sum(s * p, axis=-1) * inv
    q = np.cross(s, e1)
    v = np.sum(d * q, axis=-1) * inv
    t = np.sum(e2 * q, axis=-1) * inv
    w = 1 - u - v
    hit = ok & (u >= 0) & (v >= 0) & (w >= 0) & (t > 0) & (t < t_max)
    near_edge = ok & (np.minimum(np.minimum(u, v), w) > -EDGE_MARGIN) & (t > -EDGE_MARGIN) & (t < t_max + EDGE_MARGIN)
    t_hit = np.where(hit, t, np.inf)
    nearest = np.argmin(t_hit, axis=1)
    t_near = t_hit[np.arange(len(t_hit)), nearest]
    prim = np.where(np.isfinite(t_near), nearest, -1)
    # Ambiguous: a barely-hit or barely-missed triangle competes with the answer.
    close_call = near_edge & (np.abs(np.minimum(np.minimum(u, v), w)) < EDGE_MARGIN)
    t_candidate = np.where(close_call, t, np.inf)
    reach = np.where(np.isfinite(t_near), t_near, t_max)[:, None] + EDGE_MARGIN
    competing = np.any(close_call & (t_candidate <= reach), axis=1)
    second = np.sort(t_hit, axis=1)[:, 1] if t_hit.shape[1] > 1 else np.full(len(t_hit), np.inf)
    with np.errstate(invalid="ignore"):          # inf - inf where a ray hits nothing
        ambiguous = competing | (np.abs(second - t_near) < EDGE_MARGIN) | (np.abs(t_near - t_max) < EDGE_MARGIN)
    ambiguous |= np.isfinite(t_near) & (t_near < EDGE_MARGIN)
    return t_near, prim, ambiguous


def triangle_scene(triangles) -> Scene:
    triangles = np.asarray(triangles, np.float32)
    mesh = Mesh("soup", triangles.reshape(-1, 3), np.arange(3 * len(triangles), dtype=np.uint32).reshape(-1, 3),
                "grey")
    return Scene(Camera([0, 0, 5], [0, 0, 0]), [mesh], {"grey": Material()})


# -- multiply-add contraction --------------------------------------------------------------------------
# WGSL lets a driver contract a*b + c into one rounding (NVIDIA does) and lets fma() round once or twice
# (lavapipe rounds twice and contracts nothing). So that lavapipe shows what a contracting driver would
# do, tests compile the ray queries twice: as they are (`driver`) and with every fma() in them fused
# (`fused`: replaced by FUSED_MULTIPLY_ADD), and can swap in another edge function (the pre-fix one).
CONTRACTIONS = ("driver", "fused")
FUSED_MULTIPLY_ADD = """
// a*b + c rounded once, for drivers whose fma() rounds twice: the product's rounding error (Dekker's,
// with halves split off by bit masks) added to the rounded sum, which is exact where a*b and c nearly
// cancel (the case that decides an edge function's sign). The xor with a zero that the compiler
// cannot know stops lavapipe's optimiser from folding the correction away.
fn split_halves(a: f32) -> vec2f {
    let high = bitcast<f32>(bitcast<u32>(a) & 0xfffff000u);
    return vec2f(high, a - high);
}

fn fused_multiply_add(a: f32, b: f32, c: f32) -> f32 {
    let product = a * b;
    let sa = split_halves(a);
    let sb = split_halves(b);
    let product_error = ((sa.x * sb.x - product) + sa.x * sb.y + sa.y * sb.x) + sa.y * sb.y;
    let unknown_zero = u32(bvh_node_count() == 0u);
    return bitcast<f32>(bitcast<u32>(product + c) ^ unknown_zero) + product_error;
}
"""
# The edge function before the fix (w0 = cx * by - cy * bx) as a contracting driver may compute it: this
# form gives the 2 leaks the H100 showed on the original grid rays (the first 193 of grid_edge_rays).
PRE_FIX_EDGE_FUNCTION = "return fma(-p.y, q.x, p.x * q.y);"


def compiled_as(code: str, contraction: str, edge_function: str | None = None) -> str:
    """``code`` (composed, importing accel/bvh.wgsl) as a driver with ``contraction`` would run it."""
    if edge_function is not None:
        code, count = re.subn(r"(fn edge_function\(p: vec2f, q: vec2f\) -> f32 \{)[^}]*\}",
                              lambda m: f"{m.group(1)}\n    {edge_function}\n}}", code)
        assert count == 1
    if contraction == "fused":
        code = re.sub(r"\bfma\(", "fused_multiply_add(", code) + FUSED_MULTIPLY_ADD
    return code


def ray_query(gpu, geometry, contraction: str = "driver", edge_function: str | None = None) -> RayQuery:
    query = query_for(gpu, geometry)
    if contraction != "driver" or edge_function is not None:
        code = compiled_as(compose_with_traversal(gpu, "accel/ray_query.wgsl", traversal_for(geometry),
                                                  replacements=geometry.kernel_modules),
                           contraction, edge_function)
        query.pipelines = {entry: gpu.compute_pipeline(code, entry, label=f"ray_query.{entry} ({contraction})")
                           for entry in query.pipelines}
    return query


def check_against_brute_force(gpu, triangles, origins, dirs, t_max=np.inf, min_clear=0.9, contraction="driver",
                              layout="threaded"):
    geometry = variant_geometry(triangle_scene(triangles), layout)
    query = ray_query(gpu, geometry, contraction)
    rays = query_rays(origins, dirs, t_max)
    hits, _ = query.intersect(rays)
    occluded = query.occluded(rays)
    t_ref, prim_ref, ambiguous = brute_force(geometry.triangles, origins, dirs, t_max)
    clear = ~ambiguous
    assert clear.mean() >= min_clear, f"only {clear.mean():.0%} of rays are unambiguous: a weak test"
    hit_ref = prim_ref >= 0
    ours_hit = hits["prim"] != NO_HIT
    np.testing.assert_array_equal(ours_hit[clear], hit_ref[clear], "hit/miss differs from brute force")
    np.testing.assert_array_equal(hits["prim"][clear & hit_ref], prim_ref[clear & hit_ref])
    both = clear & hit_ref
    np.testing.assert_allclose(hits["t"][both], t_ref[both], rtol=1e-4, atol=1e-5)
    np.testing.assert_array_equal(occluded[clear], hit_ref[clear], "scene_occluded differs from brute force")
    assert np.all(hits["t"][~ours_hit] == np.float32(t_max)), "a miss must report t = t_max"
    uv = np.stack([hits["u"], hits["v"]], axis=1)[ours_hit]
    assert np.all(uv >= -1e-6) and np.all(uv.sum(axis=1) <= 1 + 1e-5)
    return hits, geometry


# -- BVH structure (no GPU) ---------------------------------------------------------------------------
def check_structure(triangles, bvh):
    nodes = bvh.nodes
    assert np.array_equal(np.sort(bvh.order), np.arange(len(triangles))), "every triangle exactly once"
    flat = zero_area(triangles)
    in_leaves = len(triangles) - np.count_nonzero(flat)
    assert not np.any(flat[bvh.order[:in_leaves]]), "zero-area triangles come last"
    leaf = nodes["count"] > 0
    covered = np.zeros(in_leaves, int)
    for index in np.nonzero(leaf)[0]:
        first, count = nodes["first"][index], nodes["count"][index]
        covered[first:first + count] += 1
        tri = triangles[bvh.order[first:first + count]]
        assert np.all(tri.min(axis=(0, 1)) >= nodes["lo"][index]) and np.all(tri.max(axis=(0, 1)) <= nodes["hi"][index])
    assert np.all(covered == 1), "leaf ranges must tile the triangles of non-zero area"
    interior = np.nonzero(~leaf)[0]
    children = nodes["first"][interior].astype(np.int64)
    assert np.all(children > interior) and np.all(children + 1 < len(nodes))
    for child in (children, children + 1):
        assert np.all(nodes["lo"][child] >= nodes["lo"][interior]) and np.all(nodes["hi"][child] <= nodes["hi"][interior])
    referenced = np.concatenate([[0], children, children + 1])
    assert np.array_equal(np.sort(referenced), np.arange(len(nodes))), "every node reachable exactly once"
    assert bvh.depth() <= MAX_DEPTH


def test_structure_random_soup():
    rng = np.random.default_rng(1)
    centers = rng.uniform(-5, 5, (3000, 1, 3))
    triangles = (centers + rng.normal(0, 0.2, (3000, 3, 3))).astype(np.float32)
    bvh = build_bvh(triangles)
    check_structure(triangles, bvh)
    sizes = bvh.leaf_sizes
    assert sizes.max() <= MAX_LEAF_SIZE and 1.5 <= sizes.mean() <= MAX_LEAF_SIZE, sizes.mean()


def test_small_leaves_split_further_and_reorder_the_geometry():
    """A tree built with SMALL_LEAF_TRAVERSAL_COST is as sound and has smaller leaves; a geometry asked for
    such a variant carries each triangle's attributes along into the new order, once per geometry."""
    rng = np.random.default_rng(2)
    centers = rng.uniform(-5, 5, (3000, 1, 3))
    triangles = (centers + rng.normal(0, 0.2, (3000, 3, 3))).astype(np.float32)
    default, small = build_bvh(triangles), build_bvh(triangles, SMALL_LEAF_TRAVERSAL_COST)
    check_structure(triangles, small)
    assert small.leaf_sizes.mean() < 0.6 * default.leaf_sizes.mean(), (small.leaf_sizes.mean(),
                                                                       default.leaf_sizes.mean())
    geometry = GeometryBuffers.build(triangle_scene(triangles))
    geometry = dataclasses.replace(geometry, object_ids=np.arange(len(triangles), dtype=np.uint32))
    rebuilt = geometry.as_variant("wide8+small-leaves+rows")
    assert (rebuilt.layout, rebuilt.small_leaves, rebuilt.row_loads) == ("wide8", True, True)
    assert rebuilt.variant == "wide8+small-leaves+rows"
    assert rebuilt.bvh.leaf_sizes.mean() < 0.6 * geometry.bvh.leaf_sizes.mean()
    moved = rebuilt.object_ids           # where each of geometry's triangles went
    np.testing.assert_array_equal(rebuilt.triangles, geometry.triangles[moved])
    np.testing.assert_array_equal(rebuilt.shading_normals, geometry.shading_normals[moved])
    assert sorted(moved) == list(range(len(triangles)))
    assert geometry.as_variant("wide+small-leaves").bvh is rebuilt.bvh
    assert rebuilt.as_variant("wide").bvh is not geometry.bvh and not rebuilt.as_variant("wide").small_leaves
    with pytest.raises(ValueError, match="unknown BVH variant"):
        geometry.as_variant("threaded+rows+small-leaves")


@pytest.mark.parametrize("count", [1, 2, 7, 40])
def test_box_bvh_has_one_box_per_leaf(count):
    """build_box_bvh (a two-level scene's top level): 2n - 1 nodes, each box alone in a leaf whose
    bounds are its own, every parent around its children; repeated boxes too."""
    rng = np.random.default_rng(count)
    lo = rng.uniform(-3, 3, (count, 3)).astype(np.float32)
    lo[count // 2:] = lo[:count - count // 2]                 # repeats
    hi = lo + rng.uniform(0, 1, (count, 3)).astype(np.float32)
    bvh = build_box_bvh(lo, hi)
    nodes = bvh.nodes
    assert len(nodes) == 2 * count - 1 and np.all(bvh.leaf_sizes == 1)
    leaf = np.flatnonzero(nodes["count"] > 0)
    boxes = bvh.order[nodes["first"][leaf]]
    assert np.array_equal(np.sort(boxes), np.arange(count))
    np.testing.assert_array_equal(nodes["lo"][leaf], lo[boxes])
    np.testing.assert_array_equal(nodes["hi"][leaf], hi[boxes])
    interior = np.flatnonzero(nodes["count"] == 0)
    for child in (nodes["first"][interior], nodes["first"][interior] + 1):
        assert np.all(nodes["lo"][child] >= nodes["lo"][interior])
        assert np.all(nodes["hi"][child] <= nodes["hi"][interior])


def test_structure_identical_and_degenerate_triangles():
    same = np.tile(np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], np.float32), (500, 1, 1))
    points = np.zeros((300, 3, 3), np.float32)      # zero-area: all three vertices coincide
    triangles = np.concatenate([points[:100], same, points[100:]])
    bvh = build_bvh(triangles)
    check_structure(triangles, bvh)
    assert bvh.leaf_sizes.max() <= MAX_LEAF_SIZE and bvh.leaf_sizes.sum() == 500


def collinear_triangles(rng, count):
    """Triangles whose float32 vertices lie exactly on one line (dyadic points on a dyadic direction),
    distinct, and a ray target on each line."""
    start = rng.integers(-64, 64, (count, 1, 3)) / 64.0
    step = rng.integers(-32, 32, (count, 1, 3)) / 256.0 + [[[1 / 512, 0, 0]]]   # never zero
    steps = np.stack([rng.choice(np.arange(-3, 4), 3, replace=False) for _ in range(count)])[:, :, None]
    target = start[:, 0] + rng.uniform(-3, 3, (count, 1)) * step[:, 0]
    return (start + steps * step).astype(np.float32), target


def test_zero_area_is_exact():
    """Collinear and repeated vertices are flagged; moving one vertex of them by one float32 ulp, or
    any ordinary triangle, is not."""
    rng = np.random.default_rng(12)
    collinear, _ = collinear_triangles(rng, 200)
    assert np.all(zero_area(collinear))
    nudged = collinear.copy()
    nudged[:, 2, 1] = np.nextafter(nudged[:, 2, 1], np.float32(np.inf))
    assert not np.any(zero_area(nudged))
    repeated = rng.uniform(-1, 1, (200, 3, 3)).astype(np.float32)
    repeated[:, 1] = repeated[:, rng.choice([0, 2])]
    assert np.all(zero_area(repeated))
    slivers = rng.uniform(-1, 1, (200, 1, 3)) + rng.uniform(0, 1, (200, 3, 1)) * rng.uniform(-1, 1, (200, 1, 3))
    slivers[:, :, 0] += rng.uniform(-1e-5, 1e-5, (200, 3))
    assert not np.any(zero_area(slivers.astype(np.float32)))
    assert not np.any(zero_area(rng.uniform(-1e30, 1e30, (200, 3, 3)).astype(np.float32)))


def test_threaded_layout_matches_traversal():
    """threaded_nodes is the depth-first order of the tree with correct skip indices; every triangle
    is owned by exactly one node, inside that node's box: a leaf of the original tree, or one of its
    ancestors (at most one lifted triangle per interior node). Packed as accel/geometry_bindings.wgsl
    unpacks it."""
    bindings = read_wgsl("accel/geometry_bindings.wgsl")
    bits = re.search(r"const LEAF_COUNT_BITS: u32 = (\d+)u;", bindings)
    mask = re.search(r"const LEAF_COUNT_MASK: u32 = (\d+)u;", bindings)
    assert int(bits.group(1)) == LEAF_COUNT_BITS and int(mask.group(1)) == (1 << LEAF_COUNT_BITS) - 1
    rng = np.random.default_rng(10)
    triangles = rng.uniform(-1, 1, (700, 3, 3)).astype(np.float32)
    bvh = build_bvh(triangles)
    order, skips, leaf_of = [], {}, {}

    def walk(node, ancestors):           # recursive reference: position, subtree end, leaf ranges
        order.append(node)
        if bvh.nodes["count"][node] == 0:
            walk(int(bvh.nodes["first"][node]), ancestors + [node])
            walk(int(bvh.nodes["first"][node]) + 1, ancestors + [node])
        else:
            first, count = int(bvh.nodes["first"][node]), int(bvh.nodes["count"][node])
            leaf_of.update({slot: ancestors + [node] for slot in range(first, first + count)})
        skips[node] = len(order)

    walk(0, [])
    threaded = threaded_nodes(bvh)
    assert threaded.itemsize == 32 and len(threaded) == bvh.node_count
    np.testing.assert_array_equal(threaded["lo"], bvh.nodes["lo"][order])
    np.testing.assert_array_equal(threaded["hi"], bvh.nodes["hi"][order])
    np.testing.assert_array_equal(threaded["skip"], [skips[n] for n in order])
    owned_count = threaded["triangles"] & ((1 << LEAF_COUNT_BITS) - 1)
    owned_first = threaded["triangles"] >> LEAF_COUNT_BITS
    owner = np.full(len(triangles), -1)
    for position, node in enumerate(order):
        for slot in range(owned_first[position], owned_first[position] + owned_count[position]):
            assert owner[slot] == -1, "a triangle owned twice"
            owner[slot] = node
            assert node in leaf_of[slot], "a triangle lifted to a node that is not above its leaf"
    assert np.all(owner >= 0), "every triangle is owned"
    interior = bvh.nodes["count"][order] == 0
    assert np.all(owned_count[interior] <= 1) and np.any(owned_count[interior] == 1)
    assert np.all(owned_count[~interior] >= 1), "lifting never empties a leaf"


@pytest.mark.parametrize("count", [1, 5, 700])
def test_wide_layout_collapses_the_binary_tree(count):
    """wide_nodes keeps the binary tree's leaves (each referenced once, with its box) and opens its
    interior nodes into wide nodes of 2 to 4 children, each reached once from a parent whose box for
    it holds its children's; the walk's stack (wgsl/accel/walk_wide.wgsl) is sized as WIDE_STACK_SIZE."""
    walk = read_wgsl("accel/walk_wide.wgsl")
    assert int(re.search(r"const WIDE_STACK_SIZE: u32 = (\d+)u;", walk).group(1)) == WIDE_STACK_SIZE
    assert int(re.search(r"const WIDE_LEAF: u32 = (0x[0-9a-f]+)u;", walk).group(1), 16) == WIDE_LEAF
    assert int(re.search(r"const WIDE_EMPTY: u32 = (0x[0-9a-f]+)u;", walk).group(1), 16) == WIDE_EMPTY
    bindings = read_wgsl("accel/geometry_bindings.wgsl")
    assert int(re.search(r"const WIDE_NODE_WORDS: u32 = (\d+)u;", bindings).group(1)) * 4 == wide_nodes(
        build_bvh(np.eye(3, dtype=np.float32)[None])).itemsize
    rng = np.random.default_rng(12)
    triangles = rng.uniform(-1, 1, (count, 3, 3)).astype(np.float32)
    bvh = build_bvh(triangles)
    wide = wide_nodes(bvh)
    binary_leaves = {(int(n["first"]), int(n["count"])): (n["lo"], n["hi"]) for n in bvh.nodes if n["count"] > 0}
    seen_leaves, parents, levels = [], {0: None}, {0: 1}
    for index, node in enumerate(wide):
        children = node["children"]
        used = children != WIDE_EMPTY
        assert used.sum() >= min(2, len(binary_leaves)) and np.all(used[:used.sum()]), "children fill slots first"
        assert np.all(np.isinf(node["lo"][:, ~used])) and np.all(np.isinf(node["hi"][:, ~used]))
        for slot in np.flatnonzero(used):
            ref = int(children[slot])
            lo, hi = node["lo"][:, slot], node["hi"][:, slot]
            if ref & WIDE_LEAF:
                leaf = ((ref & ~WIDE_LEAF) >> LEAF_COUNT_BITS, ref & ((1 << LEAF_COUNT_BITS) - 1))
                seen_leaves.append(leaf)
                np.testing.assert_array_equal(binary_leaves[leaf][0], lo)
                np.testing.assert_array_equal(binary_leaves[leaf][1], hi)
            else:
                assert ref > index and ref not in parents, "every wide node reached once, from above"
                parents[ref], levels[ref] = (index, slot), levels[index] + 1
                child = wide[ref]
                used_below = child["children"] != WIDE_EMPTY
                assert np.all(child["lo"][:, used_below] >= lo[:, None]) and np.all(child["hi"][:, used_below] <= hi[:, None])
    assert sorted(seen_leaves) == sorted(binary_leaves), "the binary tree's leaves, each once"
    assert sorted(parents) == list(range(len(wide)))
    assert max(levels.values()) * (WIDTH - 1) <= WIDE_STACK_SIZE
    interior = int(np.sum(bvh.nodes["count"] == 0))
    assert len(wide) <= max(1, interior // 2 + 1)


@pytest.mark.parametrize("offset, spread", [(0.0, 1.0), (1e5, 1.0), (-3e3, 1e-3), (0.0, 1e4)])
def test_quantized_wide_boxes_contain_the_boxes(offset, spread):
    """Layout "wide8": each child's box decoded as the GPU decodes it (f32, origin + q · 2^e) contains the
    box it stands for, tightly (a few hundredths of its size at most on a grid of 254 steps), far from
    the origin and for boxes small against their coordinates too; the references are the wide node's,
    empty slots decode inverted, and a tree of no triangle with area decodes to boxes no ray enters."""
    rng = np.random.default_rng(7)
    triangles = (offset + spread * (rng.normal(0, 1, (4000, 1, 3)) + rng.normal(0, 0.02, (4000, 3, 3))))
    wide = wide_nodes(build_bvh(triangles.astype(np.float32)))
    words = quantized_wide_nodes(wide)
    lo, hi = dequantized_boxes(words)
    used = (wide["children"] != WIDE_EMPTY)[:, None, :]
    assert np.all(np.where(used, lo <= wide["lo"], True)) and np.all(np.where(used, hi >= wide["hi"], True))
    union = np.where(used, wide["hi"], -np.inf).max(2) - np.where(used, wide["lo"], np.inf).min(2)   # (N, 3)
    slack = np.where(used, np.maximum(wide["lo"] - lo, hi - wide["hi"]), 0.0)
    assert np.all(slack <= 2.5 * union[:, :, None] / 254 + 1e-6 * (abs(offset) + spread))
    np.testing.assert_array_equal(words[:, 10:14], wide["children"])
    assert np.all(np.where(used, True, lo > hi))
    flat = wide_nodes(build_bvh(np.zeros((3, 3, 3), np.float32)))   # no area: a root at +inf
    assert np.all(np.isinf(dequantized_boxes(quantized_wide_nodes(flat))[0][:, :, 0]))


def test_depth_limit_is_enforced(monkeypatch):
    monkeypatch.setattr(bvh_module, "MAX_DEPTH", 4)
    rng = np.random.default_rng(2)
    triangles = rng.uniform(-1, 1, (2000, 3, 3)).astype(np.float32)
    bvh = build_bvh(triangles)
    assert bvh.depth() <= 4


def test_zero_triangles_rejected():
    with pytest.raises(ValueError, match="zero triangles"):
        build_bvh(np.zeros((0, 3, 3), np.float32))


# -- traversal against brute force ------------------------------------------------------------------
@pytest.mark.parametrize("layout", LAYOUTS)
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1), triangle_count=st.integers(1, 300), spread=st.floats(0.05, 1.0))
def test_random_soup_matches_brute_force(gpu, layout, seed, triangle_count, spread):
    rng = np.random.default_rng(seed)
    centers = rng.uniform(-1, 1, (triangle_count, 1, 3))
    triangles = centers + rng.normal(0, spread, (triangle_count, 3, 3))
    origins = rng.uniform(-2, 2, (256, 3))
    targets = rng.uniform(-1, 1, (256, 3))
    dirs = targets - origins
    t_max = rng.choice([np.inf, 0.5, 1.0])
    check_against_brute_force(gpu, triangles, origins, dirs, t_max, min_clear=0.8, layout=layout)


def _grid(n=8, z=0.0):
    """An n×n grid of unit quads in the plane z, two triangles each, sharing edges and vertices."""
    xs = np.arange(n, dtype=np.float64)
    x, y = np.meshgrid(xs, xs, indexing="ij")
    a = np.stack([x, y, np.full_like(x, z)], -1).reshape(-1, 3)
    b, c, d = a + [1, 0, 0], a + [1, 1, 0], a + [0, 1, 0]
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.float32)


def grid_edge_rays():
    """Rays at the shared vertices and edges of _grid(): exactly at interior vertices and dyadic points
    of the edges from above, and at random points of random edges from above and below, from near and
    far."""
    ticks = np.arange(1, 7.01, 0.5)      # interior vertices and midpoints of the axis-aligned edges
    x, y = np.meshgrid(ticks, ticks, indexing="ij")
    on_grid_lines = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], 1)
    cells, fractions = np.meshgrid(np.arange(1, 7), [0.125, 0.25, 0.5, 0.75], indexing="ij")
    on_diagonals = np.stack([(cells + fractions).ravel(), (cells + fractions).ravel(), np.zeros(cells.size)], 1)
    targets = np.concatenate([on_grid_lines, on_diagonals])
    rng = np.random.default_rng(3)
    origins = targets + np.column_stack([rng.uniform(-1, 1, (len(targets), 2)), np.full(len(targets), 2.0)])
    count = 3000
    corner = rng.integers(1, 7, (count, 2)).astype(np.float64)
    along = rng.uniform(0, 1, count)
    direction = np.array([[1.0, 1.0], [1.0, 0.0], [0.0, 1.0]])[rng.integers(0, 3, count)]   # diagonal, x, y
    random_targets = np.column_stack([corner + along[:, None] * direction, np.zeros(count)])
    spread = rng.choice([1.0, 10.0, 100.0], count)[:, None]
    height = rng.choice([-1.0, 1.0], count) * rng.uniform(0.1, 2, count) * spread[:, 0]
    random_origins = random_targets + np.column_stack([rng.uniform(-1, 1, (count, 2)) * spread, height])
    return np.concatenate([origins, random_origins]), np.concatenate([targets, random_targets])


@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("contraction", CONTRACTIONS)
def test_watertight_at_shared_edges_and_vertices(gpu, contraction, layout):
    """Rays aimed exactly at shared vertices and edges of a grid, from random directions, must not
    slip through, whether or not the driver fuses multiply-adds."""
    origins, targets = grid_edge_rays()
    geometry = variant_geometry(triangle_scene(_grid()), layout)
    hits, _ = ray_query(gpu, geometry, contraction).intersect(query_rays(origins, targets - origins))
    assert np.all(hits["prim"] != NO_HIT), f"{np.sum(hits['prim'] == NO_HIT)} rays leaked through the grid"
    np.testing.assert_allclose(hits["t"], 1.0, rtol=1e-5)


def test_pre_fix_edge_function_leaks_when_fused(gpu):
    """The control for the test above: the edge function as it was before, compiled with fused
    multiply-adds, lets rays through (as it did on the H100), so the emulation and the rays can catch it.
    The emulation is exact where the driver compiles its arithmetic as written (lavapipe, which CI runs);
    NVIDIA's compiler contracts the emulation's own products too (no leaks there), so on a GPU the
    driver-contraction test above is the one that speaks."""
    if gpu.adapter.info.get("adapter_type") != "CPU":
        pytest.skip("the fused emulation is exact only on a driver that contracts nothing (lavapipe)")
    origins, targets = grid_edge_rays()
    geometry = GeometryBuffers.build(triangle_scene(_grid()))
    query = ray_query(gpu, geometry, "fused", PRE_FIX_EDGE_FUNCTION)
    hits, _ = query.intersect(query_rays(origins, targets - origins))
    assert np.sum(hits["prim"] == NO_HIT) >= 10


def run_kernel(gpu, code: str, inputs: np.ndarray, out_dtype, out_shape, nodes: np.ndarray | None = None):
    """Run ``main`` of ``code`` (accel/bvh.wgsl plus a kernel over group 1: ``inputs``, output) on one
    invocation per output row; ``nodes``: the BVH node words of group 0 binding 0, where it reads them."""
    pipeline = gpu.compute_pipeline(code, "main")
    out = gpu.storage(int(np.prod(out_shape)) * np.dtype(out_dtype).itemsize)
    encoder = gpu.device.create_command_encoder()
    compute = encoder.begin_compute_pass()
    compute.set_pipeline(pipeline)
    if nodes is not None:
        compute.set_bind_group(0, gpu.bind_group(pipeline, [gpu.upload(nodes)]))
    compute.set_bind_group(1, gpu.bind_group(pipeline, [gpu.upload(inputs), out], group=1))
    compute.dispatch_workgroups((out_shape[0] + 63) // 64)
    compute.end()
    gpu.device.queue.submit([encoder.finish()])
    return gpu.read(out, out_dtype, shape=out_shape)


BOX_KERNEL = """
@group(1) @binding(0) var<storage, read> cases: array<vec4f>;   // origin, dir, lo, hi
@group(1) @binding(1) var<storage, read_write> entered: array<u32>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3u) {
    if (id.x >= arrayLength(&entered)) { return; }
    let k = 4u * id.x;
    let ray = traversal_ray(cases[k].xyz, cases[k + 1u].xyz);
    let lo = cases[k + 2u].xyz;
    let hi = cases[k + 3u].xyz;
    // the box in all four columns of a wide node (accel/walk_wide.wgsl)
    let wide = wide_entries(vec4f(lo.x), vec4f(lo.y), vec4f(lo.z), vec4f(hi.x), vec4f(hi.y), vec4f(hi.z), ray, 3.0e38);
    entered[id.x] = u32(box_hit(lo, hi, ray, 3.0e38)) | (u32(all(wide < vec4f(WIDE_MISS))) << 1u);
}
"""


def test_box_test_enters_boxes_touched_at_an_edge(gpu):
    """box_hit, and the wide walk's four-box form of it, enter every box that the ray meets (in exact
    arithmetic), here rays aimed at points on box edges from near and far. (With t = plane · (1/dir) −
    origin · (1/dir), 3 % of them missed.)"""
    rng = np.random.default_rng(15)
    count = 8192
    lo = rng.uniform(-8, 8, (count, 3)).astype(np.float32)
    hi = (lo + rng.uniform(0, 2, (count, 3)) * (rng.uniform(size=(count, 3)) > 0.3)).astype(np.float32)   # some flat
    on_bound = np.where(rng.uniform(size=(count, 3)) < 0.5, lo, hi)
    free_axis = np.arange(3) == rng.integers(0, 3, (count, 1))
    targets = np.where(free_axis, lo + rng.uniform(size=(count, 3)) * (hi - lo), on_bound)
    origins = (targets + rng.normal(0, 1, (count, 3)) * rng.choice([0.1, 1.0, 10.0], (count, 1))).astype(np.float32)
    dirs = (targets - origins).astype(np.float32)
    cases = np.stack([origins, dirs, lo, hi], axis=1)
    entered = run_kernel(gpu, compose("accel/walk_wide.wgsl") + BOX_KERNEL,
                         np.concatenate([cases, np.zeros((count, 4, 1), np.float32)], axis=2), np.uint32, (count,))
    o, d = origins.astype(np.float64), dirs.astype(np.float64)
    t0, t1 = (lo - o) / d, (hi - o) / d
    meets = np.max(np.maximum(np.minimum(t0, t1), 0), axis=1) <= np.min(np.maximum(t0, t1), axis=1)
    assert meets.mean() > 0.5
    assert np.all(entered[meets] == 3), f"{np.sum(entered[meets] != 3)} boxes missed"
    assert np.all((entered[~meets] & 1) == entered[~meets] >> 1), "the two forms differ"


EDGE_KERNEL = """
@group(1) @binding(0) var<storage, read> edges: array<vec4f>;      // (p, q) in ray space
@group(1) @binding(1) var<storage, read_write> out: array<vec4f>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3u) {
    if (id.x >= arrayLength(&edges)) { return; }
    let p = edges[id.x].xy;
    let q = edges[id.x].zw;
    out[id.x] = vec4f(edge_function(p, q), edge_function(q, p), fma(p.x, q.y, -(p.y * q.x)), fma(q.x, p.y, -(q.y * p.x)));
}
"""


@pytest.mark.parametrize("contraction", CONTRACTIONS)
def test_edge_function_is_antisymmetric(gpu, contraction):
    """accel/walk_tree.wgsl's edge_function(q, p) is exactly -edge_function(p, q), and 0 when p == q, for
    edges that pass within rounding of the ray (the origin), fused or not; the fused emulation is exact
    there, and fusing the naive form a*b - c*d does break both properties."""
    rng = np.random.default_rng(13)
    p = rng.uniform(-2, 2, (4096, 2))
    q = -p * rng.uniform(0.2, 5, (4096, 1)) + rng.normal(0, 1e-6, (4096, 2))
    edges = np.concatenate([p, q], axis=1).astype(np.float32)
    edges[:256, 2:] = edges[:256, :2]
    code = compiled_as(compose("accel/bvh.wgsl") + EDGE_KERNEL, contraction)
    nodes = np.arange(8, dtype=np.uint32) if contraction == "fused" else None   # the emulation reads word 3
    forward, backward, naive_forward, naive_backward = run_kernel(gpu, code, edges, np.float32,
                                                                  (len(edges), 4), nodes).T
    np.testing.assert_array_equal(backward, -forward)
    assert np.all(forward[:256] == 0)
    if contraction == "fused":
        px, py, qx, qy = edges.T.astype(np.float64)
        fused = (px * qy - (edges[:, 1] * edges[:, 2]).astype(np.float64)).astype(np.float32)   # exact, then rounded
        np.testing.assert_array_equal(naive_forward, fused)
        assert np.sum(naive_backward != -naive_forward) > 100 and np.all(naive_forward[:256] != 0)


@pytest.mark.parametrize("layout", LAYOUTS)
def test_axis_aligned_rays(gpu, layout):
    """Rays along ±x, ±y, ±z (zero direction components) through a closed cube and random triangles."""
    rng = np.random.default_rng(4)
    cube = trimesh.creation.box(extents=(1, 1, 1))
    triangles = np.concatenate([cube.vertices[cube.faces], rng.uniform(-2, 2, (60, 3, 3))])
    axes = np.concatenate([np.eye(3), -np.eye(3)])
    dirs = axes[rng.integers(0, 6, 600)]
    origins = rng.uniform(-2, 2, (600, 3))
    hits, _ = check_against_brute_force(gpu, triangles, origins, dirs, layout=layout)
    # Rays starting inside the cube must always hit it (it is closed).
    inside = np.all(np.abs(origins) < 0.49, axis=1)
    assert np.all(hits["prim"][inside] != NO_HIT)


def test_grazing_rays(gpu):
    """Rays in or almost in the grid's plane: exactly coplanar rays hit nothing; near-coplanar ones
    hit where brute force says."""
    triangles = _grid()
    rng = np.random.default_rng(5)
    origins = np.column_stack([rng.uniform(-1, 0, 400), rng.uniform(0.5, 7.5, 400), np.zeros(400)])
    dirs = np.column_stack([np.ones(400), rng.uniform(-0.2, 0.2, 400), np.zeros(400)])
    geometry = GeometryBuffers.build(triangle_scene(triangles))
    query = query_for(gpu, geometry)
    hits, _ = query.intersect(query_rays(origins, dirs))
    assert np.all(hits["prim"] == NO_HIT), "a ray inside the plane of a triangle must not hit it"
    origins[:, 2] = 1e-3
    dirs[:, 2] = -rng.uniform(1e-4, 1e-3, 400)
    check_against_brute_force(gpu, triangles, origins, dirs)


@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("contraction", CONTRACTIONS)
def test_degenerate_triangles_never_hit(gpu, contraction, layout):
    """Near-degenerate slivers, repeated vertices and exactly collinear ones (each aimed at by a ray
    through its line: before the fix, rounding into ray space gave 7 % of such rays a hit)."""
    rng = np.random.default_rng(6)
    good = rng.uniform(-1, 1, (100, 3, 3))
    line = rng.uniform(-1, 1, (100, 1, 3)) + rng.uniform(0, 1, (100, 3, 1)) * rng.uniform(-1, 1, (100, 1, 3))
    point = np.repeat(rng.uniform(-1, 1, (100, 1, 3)), 3, axis=1)
    collinear, on_lines = collinear_triangles(rng, 100)
    triangles = np.concatenate([good, line, point, collinear])
    origins = rng.uniform(-2, 2, (1024, 3))
    targets = np.concatenate([rng.uniform(-1, 1, (512, 3)), on_lines[rng.integers(0, 100, 512)]])
    hits, geometry = check_against_brute_force(gpu, triangles, origins, targets - origins, min_clear=0.85,
                                               contraction=contraction, layout=layout)
    hit_prims = hits["prim"][hits["prim"] != NO_HIT]
    area = np.linalg.norm(np.cross(geometry.triangles[:, 1] - geometry.triangles[:, 0],
                                   geometry.triangles[:, 2] - geometry.triangles[:, 0]), axis=1)
    assert len(hit_prims) > 50 and np.all(area[hit_prims] > 1e-6)


@pytest.mark.parametrize("layout", LAYOUTS)
def test_scene_of_only_zero_area_triangles_hits_nothing(gpu, layout):
    rng = np.random.default_rng(14)
    collinear, on_lines = collinear_triangles(rng, 50)
    geometry = variant_geometry(triangle_scene(collinear), layout)
    origins = rng.uniform(-2, 2, (256, 3))
    rays = query_rays(origins, on_lines[rng.integers(0, 50, 256)] - origins)
    query = query_for(gpu, geometry)
    hits, _ = query.intersect(rays)
    assert np.all(hits["prim"] == NO_HIT) and not np.any(query.occluded(rays))


@pytest.mark.parametrize("layout", LAYOUTS)
def test_rays_leaving_surfaces(gpu, layout):
    """Rays spawned on surfaces through offset_ray_origin (accel/bvh.wgsl) hit what brute force from the
    offset origin hits, never their own triangle at t ≈ 0."""
    sphere = trimesh.creation.icosphere(subdivisions=2)
    triangles = np.concatenate([sphere.vertices[sphere.faces], sphere.vertices[sphere.faces] * 0.3 + [0.2, 0, 0]])
    rng = np.random.default_rng(7)
    start = rng.integers(0, len(triangles), 500)
    weights = rng.dirichlet([4, 4, 4], 500)
    points = np.einsum("nk,nkj->nj", weights, triangles[start])
    normals = np.cross(triangles[start, 1] - triangles[start, 0], triangles[start, 2] - triangles[start, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    dirs = rng.normal(size=(500, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    dirs[np.abs(np.sum(dirs * normals, axis=1)) < 0.05] = normals[np.abs(np.sum(dirs * normals, axis=1)) < 0.05]
    geometry = variant_geometry(triangle_scene(triangles), layout)
    hits, _ = query_for(gpu, geometry).intersect(query_rays(points, dirs, offset_normals=normals))
    side = np.where(np.sum(normals * dirs, axis=1, keepdims=True) >= 0, normals, -normals)
    offset = side * 1e-5 * np.maximum(np.abs(points).max(axis=1, keepdims=True), 1.0)   # accel/bvh.wgsl's rule
    t_ref, prim_ref, ambiguous = brute_force(geometry.triangles, points + offset, dirs)
    clear = ~ambiguous
    assert clear.mean() > 0.9
    ours = hits["prim"] != NO_HIT
    np.testing.assert_array_equal(ours[clear], (prim_ref >= 0)[clear])
    both = clear & (prim_ref >= 0)
    np.testing.assert_array_equal(hits["prim"][both], prim_ref[both], "a spawned ray re-hit its own surface?")
    np.testing.assert_allclose(hits["t"][both], t_ref[both], rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize("layout", LAYOUTS)
def test_surface_attributes_at_hits(gpu, layout):
    """Material/object ids, interpolated shading normals and object motion reported at GPU hits."""
    sphere = trimesh.creation.icosphere(subdivisions=2)
    smooth = Mesh("ball", np.asarray(sphere.vertices, np.float32), np.asarray(sphere.faces, np.uint32), "metal",
                  normals=np.asarray(sphere.vertex_normals, np.float32))
    flat = Mesh("slab", np.asarray(sphere.vertices, np.float32), np.asarray(sphere.faces, np.uint32), "chalk")
    flat.keyframes = {0: np.eye(4, dtype=np.float32),
                      1: np.array([[1, 0, 0, 3], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], np.float32)}
    flat.transform = flat.keyframes[1]
    scene = Scene(Camera([0, 0, 5], [0, 0, 0]), [smooth, flat],
                  {"chalk": Material(), "metal": Material("conductor", roughness=0.1)}, frame_count=2)
    geometry = variant_geometry(scene, layout, frame=1)
    rng = np.random.default_rng(8)
    targets = np.concatenate([rng.normal(0, 0.3, (100, 3)), rng.normal(0, 0.3, (100, 3)) + [3, 0, 0]])
    origins = targets + [0, 0, 5]
    hits, surfaces = query_for(gpu, geometry).intersect(query_rays(origins, targets - origins))
    hit = hits["prim"] != NO_HIT
    assert hit.sum() > 150
    prim = hits["prim"][hit]
    np.testing.assert_array_equal(surfaces["material"][hit], geometry.material_ids[prim])
    np.testing.assert_array_equal(surfaces["object"][hit], geometry.object_ids[prim])
    on_ball = surfaces["object"][hit] == 0
    assert np.all(surfaces["material"][hit][on_ball] == 1) and np.all(surfaces["material"][hit][~on_ball] == 0)
    u, v = hits["u"][hit], hits["v"][hit]
    expected = np.einsum("nk,nkj->nj", np.stack([1 - u - v, u, v], 1), geometry.shading_normals[prim])
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    np.testing.assert_allclose(surfaces["shading_normal"][hit], expected, atol=1e-5)
    position = origins[hit] + (targets - origins)[hit] * hits["t"][hit][:, None]
    previous = position - np.where(on_ball[:, None], 0.0, [3.0, 0, 0])
    np.testing.assert_allclose(surfaces["previous_position"][hit], previous, atol=1e-4)


@pytest.mark.parametrize("layout", LAYOUTS)
def test_bunny_traversal(gpu, layout):
    if not BUNNY.exists():
        pytest.skip(f"{BUNNY} not present")
    mesh = trimesh.load(BUNNY, force="mesh", process=False)
    triangles = np.asarray(mesh.vertices, np.float32)[mesh.faces]
    check_structure(triangles, build_bvh(triangles))
    rng = np.random.default_rng(9)
    center, size = triangles.reshape(-1, 3).mean(0), np.ptp(triangles.reshape(-1, 3), 0).max()
    origins = center + rng.normal(0, size, (64, 3))
    dirs = center + rng.normal(0, size * 0.2, (64, 3)) - origins
    check_against_brute_force(gpu, triangles, origins, dirs, min_clear=0.85, layout=layout)
