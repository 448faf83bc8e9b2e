"""The BVH walks (wgsl/accel/traversal_lanes.wgsl: every invocation walks the threaded tree alone;
wgsl/accel/traversal_subgroup.wgsl: a subgroup walks it as one packet with shared fetches;
wgsl/accel/walk_wide.wgsl: every invocation walks the 4-wide tree with a stack) against brute force and
against each other, and the tracer's loop budget (wgsl/trace/trace.wgsl, LOOP_BUDGET) on paths long
enough to hit lavapipe's limit on loop passes per dispatch."""

import numpy as np
import pytest
from test_bvh import brute_force, triangle_scene

from wgpu_rt.accel.bvh import wide_nodes as bvh_wide_nodes
from wgpu_rt.passes import FrameBuffers
from wgpu_rt.scene import Camera, Material, Mesh, Scene, load_scene
from wgpu_rt.accel.geometry import (LANES_TRAVERSAL, SUBGROUP_TRAVERSAL, GeometryBuffers, traversal_module)
from wgpu_rt.scene.primitives import primitive
from wgpu_rt.accel.ray_query import NO_HIT, RayQuery, query_rays
from wgpu_rt.trace import SampleSchedule, SceneFeatures, TracePass
from wgpu_rt.trace.trace_pass import BufferPlacement

MODULES = [LANES_TRAVERSAL, SUBGROUP_TRAVERSAL]
WALKS = [(LANES_TRAVERSAL, "threaded"), (SUBGROUP_TRAVERSAL, "threaded"), (LANES_TRAVERSAL, "wide"),
         (SUBGROUP_TRAVERSAL, "wide"), (LANES_TRAVERSAL, "threaded+rows"), (LANES_TRAVERSAL, "wide+rows"),
         (LANES_TRAVERSAL, "wide8"), (SUBGROUP_TRAVERSAL, "wide8"), (LANES_TRAVERSAL, "wide8+rows"),
         (LANES_TRAVERSAL, "wide+small-leaves+rows"), (SUBGROUP_TRAVERSAL, "wide8+small-leaves")]
SIZE = (24, 16)


def _require(gpu, module):
    if module == SUBGROUP_TRAVERSAL and traversal_module(gpu) != SUBGROUP_TRAVERSAL:
        pytest.skip("this adapter does not use subgroup packets")


@pytest.mark.parametrize("module, layout", WALKS)
def test_traversal_matches_brute_force(gpu, module, layout):
    """Closest hits and occlusion of rays through a clustered soup (deep tree, lifted triangles),
    with a ray count that leaves a partial workgroup."""
    _require(gpu, module)
    rng = np.random.default_rng(11)
    centers = rng.uniform(-1, 1, (40, 1, 1, 3))
    triangles = (centers + rng.normal(0, 0.15, (40, 30, 3, 3))).reshape(-1, 3, 3)
    origins = rng.uniform(-2, 2, (1000, 3))
    dirs = rng.uniform(-1, 1, (1000, 3)) - origins
    geometry = GeometryBuffers.build(triangle_scene(triangles)).as_variant(layout)
    query = RayQuery(gpu, geometry, traversal=module)
    for t_max in (np.inf, 1.0):
        rays = query_rays(origins, dirs, t_max)
        hits, _ = query.intersect(rays)
        occluded = query.occluded(rays)
        t_ref, prim_ref, ambiguous = brute_force(geometry.triangles, origins, dirs, t_max)
        clear, hit = ~ambiguous, prim_ref >= 0
        assert clear.mean() > 0.9 and np.sum(hit[clear]) > 200
        np.testing.assert_array_equal(hits["prim"][clear], np.where(hit, prim_ref, NO_HIT)[clear])
        np.testing.assert_allclose(hits["t"][clear & hit], t_ref[clear & hit], rtol=1e-4)
        np.testing.assert_array_equal(occluded[clear], hit[clear])


def _render(gpu, scene, module, spp, max_depth=8, chunk_size=None, size=SIZE, layout="threaded", placement=None):
    features = SceneFeatures.of(scene)
    trace = TracePass(gpu, scene, GeometryBuffers.build(scene).as_variant(layout), *size, max_depth=max_depth,
                      features=features, chunk_size=chunk_size, traversal=module, placement=placement)
    buffers = FrameBuffers(gpu, *size)
    encoder = gpu.device.create_command_encoder()
    trace.clear(encoder, buffers)
    trace.execute(encoder, buffers, SampleSchedule(samples=spp))
    gpu.device.queue.submit([encoder.finish()])
    return {name: buffers.read(name) for name in ("radiance", "albedo", "normal", "depth", "spp")}


@pytest.mark.parametrize("scene_name", ["cornell", "cornell-glossy", "sun-room"])
def test_packets_render_the_image_of_lone_walks(gpu, scene_name):
    """Walking as a packet changes which nodes are visited, never which hit is closest: the frames
    agree bit for bit (idle lanes, shadow rays and path restarts included)."""
    _require(gpu, SUBGROUP_TRAVERSAL)
    scene = load_scene(scene_name)
    lone = _render(gpu, scene, LANES_TRAVERSAL, spp=3)
    packet = _render(gpu, scene, SUBGROUP_TRAVERSAL, spp=3)
    assert np.all(lone["spp"] == 3)
    for name, plane in lone.items():
        assert plane.tobytes() == packet[name].tobytes(), name


@pytest.mark.parametrize("module", MODULES)
@pytest.mark.parametrize("scene_name", ["cornell", "cornell-glossy", "sun-room"])
def test_wide_walk_renders_the_image_of_the_threaded_walk(gpu, scene_name, module):
    """The 4-wide tree, walked nearest child first alone or as a packet, finds the same closest hits and
    blockers as the threaded one: the frames agree bit for bit."""
    _require(gpu, module)
    scene = load_scene(scene_name)
    threaded = _render(gpu, scene, LANES_TRAVERSAL, spp=3)
    wide = _render(gpu, scene, module, spp=3, layout="wide")
    assert np.all(threaded["spp"] == 3)
    for name, plane in threaded.items():
        assert plane.tobytes() == wide[name].tobytes(), name


@pytest.mark.parametrize("layout", ["threaded", "wide"])
@pytest.mark.parametrize("scene_name", ["cornell", "cornell-glossy", "sun-room"])
def test_row_loads_render_the_image_of_word_loads(gpu, scene_name, layout):
    """Nodes and vertices fetched as 16-byte rows (accel/geometry_rows.wgsl) are the same records: the
    frames agree bit for bit. The geometry is kept in storage buffers, where rows apply."""
    scene = load_scene(scene_name)
    storage = BufferPlacement()
    words = _render(gpu, scene, LANES_TRAVERSAL, spp=3, layout=layout, placement=storage)
    rows = _render(gpu, scene, LANES_TRAVERSAL, spp=3, layout=f"{layout}+rows", placement=storage)
    assert np.all(words["spp"] == 3)
    for name, plane in words.items():
        assert plane.tobytes() == rows[name].tobytes(), name


def test_long_paths_in_big_chunks_stay_unbiased(gpu):
    """A rough glass ball under a white sky with 64-segment paths and 32 samples per dispatch makes
    more loop passes than lavapipe allows one dispatch (65535 per invocation; past that every loop
    stops after one pass). The kernel stops starting samples before that (LOOP_BUDGET) and folds in
    only the samples it completed, so the pixels stay unbiased (the furnace value within 1.5%) with
    the spp plane saying how many samples they hold. Counting unfinished samples darkened it by 3.5%."""
    vertices, faces, normals = primitive("sphere")
    sphere = Mesh("sphere", vertices, faces, "glass", normals=normals)
    scene = Scene(Camera(origin=[0, 0, 2.6], target=[0, 0, 0], fov=30), [sphere],
                  {"glass": Material("dielectric", ior=1.5, roughness=0.05)}, background=np.ones(3, np.float32))
    planes = _render(gpu, scene, None, spp=64, max_depth=64, chunk_size=32, size=(16, 16))
    spp = planes["spp"]
    assert spp.min() >= 8 and spp.max() <= 64
    radiance = planes["radiance"].reshape(3, -1)
    assert np.all(np.isfinite(radiance))
    assert 0.985 <= radiance.mean() <= 1.01, radiance.mean()


def test_single_node_ordering_renders_the_same_image(gpu):
    """A scene too big for 8 direction-ordered node copies walks one copy: the same closest hits."""
    from wgpu_rt.renderer import render
    from wgpu_rt.gpu import GpuContext

    small = GpuContext(adapter=gpu.adapter, device=gpu.device, features=gpu.features)
    small.__dict__["subgroup_sizes"] = gpu.subgroup_sizes
    geometry = GeometryBuffers.build(load_scene("cornell-glossy"))
    one_copy = geometry.packed_arrays(orderings=1)[0].nbytes
    small.__dict__["limits"] = {**gpu.limits, "max-storage-buffer-binding-size": 8 * one_copy - 1}
    assert geometry.orderings(small) == 1 and geometry.orderings(gpu) == 8
    options = dict(size=(16, 16), max_depth=3, aovs=())
    reference = render("cornell-glossy", ctx=gpu, **options).color
    fallback = render("cornell-glossy", ctx=small, **options).color
    np.testing.assert_allclose(fallback, reference, rtol=1e-5, atol=1e-6)


def test_renderer_takes_the_layout_from_the_environment(gpu, monkeypatch):
    """WGPU_RT_BVH=threaded / wide renders single-level scenes through that walk (the same image); an
    unknown layout is refused by name."""
    from wgpu_rt.accel import geometry
    from wgpu_rt.errors import SceneError
    from wgpu_rt.renderer import render

    laid_out = []
    monkeypatch.setattr(geometry, "wide_nodes", lambda bvh: laid_out.append(bvh) or bvh_wide_nodes(bvh))
    options = dict(size=(16, 16), spp=2, max_depth=4, aovs=(), ctx=gpu)
    monkeypatch.setenv(geometry.BVH_LAYOUT_ENV, "threaded")   # unset, a GPU walks small scenes wide
    threaded = render("cornell-glossy", **options).color
    assert not laid_out
    monkeypatch.setenv(geometry.BVH_LAYOUT_ENV, "wide")
    np.testing.assert_array_equal(render("cornell-glossy", **options).color, threaded)
    assert laid_out
    monkeypatch.setenv(geometry.BVH_LAYOUT_ENV, "octree")
    with pytest.raises(SceneError, match="WGPU_RT_BVH='octree'"):
        render("cornell-glossy", **options)
