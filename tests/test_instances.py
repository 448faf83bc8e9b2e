"""Two-level geometry (wgpu_rt.accel.geometry.InstancedGeometry, wgsl/accel/instances.wgsl): moving
meshes as instances of bottom-level BVHs built once, under a top level rebuilt per frame."""

import numpy as np
import pytest
from test_bvh import brute_force
from test_pipeline import TrafficCounter
from test_traversal import MODULES, _require

from wgpu_rt.accel.geometry import GeometryBuffers, InstancedGeometry
from wgpu_rt.accel.ray_query import NO_HIT, RayQuery, query_rays
from wgpu_rt.passes import FrameBuffers
from wgpu_rt.renderer import Renderer
from wgpu_rt.scene import Camera, Material, Mesh, Scene, load_scene
from wgpu_rt.scene.primitives import primitive
from wgpu_rt.scene.transforms import compose, rotate, scale, translate
from wgpu_rt.trace import SampleSchedule, TracePass
from wgpu_rt.trace.scene_data import FRAME_PARAMS_DTYPE

FRAMES = 4


def _soup(rng, clusters: int, per_cluster: int, spread: float) -> np.ndarray:
    centers = rng.uniform(-1, 1, (clusters, 1, 1, 3))
    return (centers + rng.normal(0, spread, (clusters, per_cluster, 3, 3))).reshape(-1, 3, 3).astype(np.float32)


def _mesh(name: str, triangles: np.ndarray, material: str = "grey") -> Mesh:
    return Mesh(name, triangles.reshape(-1, 3), np.arange(3 * len(triangles), dtype=np.uint32).reshape(-1, 3),
                material)


def moving_scene(seed: int = 5) -> Scene:
    """A static soup (two meshes) and three soups that move over FRAMES frames: rotated, scaled
    non-uniformly, mirrored, translated."""
    rng = np.random.default_rng(seed)
    static = [_mesh("static-a", _soup(rng, 10, 20, 0.1)), _mesh("static-b", _soup(rng, 5, 20, 0.1))]
    movers = [_mesh(f"mover-{i}", _soup(rng, 6, 25, 0.08)) for i in range(3)]
    for frame in range(FRAMES):
        movers[0].keyframes[frame] = compose(translate([0.3 * frame, 0, 0]), rotate([0, 1, 1], 25 * frame),
                                             scale([0.5, 0.8, 1.2]))
        movers[1].keyframes[frame] = compose(translate([-0.5, 0.2 * frame, 0.4]), scale([-0.6, 0.6, 0.6]))
        movers[2].keyframes[frame] = compose(rotate([1, 0, 0], 40 + 30 * frame), translate([0, 0, 0.3]),
                                             scale(1.5))
    scene = Scene(Camera([0, 0, 5], [0, 0, 0]), static + movers, {"grey": Material()})
    scene.frame_count = FRAMES
    return scene


def _random_rays(rng, count: int):
    origins = rng.uniform(-2.5, 2.5, (count, 3))
    targets = rng.uniform(-1.5, 1.5, (count, 3))
    return origins, targets - origins


def _check_against_brute_force(query: RayQuery, world: np.ndarray, origins, dirs):
    for t_max in (np.inf, 1.0):
        rays = query_rays(origins, dirs, t_max)
        hits, surfaces = query.intersect(rays)
        occluded = query.occluded(rays)
        t_ref, prim_ref, ambiguous = brute_force(world, origins, dirs, t_max)
        clear, hit = ~ambiguous, prim_ref >= 0
        assert clear.mean() > 0.9 and np.sum(hit[clear]) > 200 and np.sum(~hit[clear]) > 50
        np.testing.assert_array_equal(hits["prim"][clear], np.where(hit, prim_ref, NO_HIT)[clear])
        np.testing.assert_allclose(hits["t"][clear & hit], t_ref[clear & hit], rtol=1e-4)
        np.testing.assert_array_equal(occluded[clear], hit[clear])
        # Normals come back in world space, by the winding of the world triangle.
        found = clear & hit
        tri = world[prim_ref[found]].astype(np.float64)
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        np.testing.assert_allclose(surfaces["geometric_normal"][found], normal, atol=2e-3)
        np.testing.assert_allclose(surfaces["shading_normal"][found], normal, atol=2e-3)


@pytest.mark.parametrize("module", MODULES)
def test_instanced_traversal_matches_brute_force(gpu, module):
    """Closest hits, occlusion and world-space normals through static and moving instances, at the
    frame the geometry was built for and after moving it to other frames (per-frame buffers only)."""
    _require(gpu, module)
    scene = moving_scene()
    geometry = InstancedGeometry(scene, frame=1)
    assert len(geometry.levels) == 4           # the static meshes share one bottom level
    query = RayQuery(gpu, geometry, traversal=module)
    rng = np.random.default_rng(3)
    for frame in (1, 3, 0):
        if frame != geometry.frame:
            geometry.write_frame(gpu, query.geometry_buffers, frame)
        origins, dirs = _random_rays(rng, 1500)
        _check_against_brute_force(query, geometry.world_triangles(frame), origins, dirs)


def test_one_node_copy_per_bottom_level_where_eight_do_not_fit(gpu, monkeypatch):
    """With a storage binding too small for 8 direction-ordered copies of every bottom level, each gets
    one (the top level keeps its 8) and the walk still finds what brute force finds."""
    from wgpu_rt.gpu import GpuContext

    scene = moving_scene()
    geometry = InstancedGeometry(scene, frame=2)
    small = GpuContext(adapter=gpu.adapter, device=gpu.device, features=gpu.features)
    small.__dict__["subgroup_sizes"] = gpu.subgroup_sizes
    small.__dict__["limits"] = {**gpu.limits,
                                "max-storage-buffer-binding-size": geometry.node_count() * 32 - 1}
    assert geometry.orderings(small) == 1 and geometry.orderings(gpu) == 8
    # Query through the full context (the small one would refuse the rays' buffers), with one copy.
    monkeypatch.setattr(InstancedGeometry, "orderings", lambda self, ctx: 1)
    query = RayQuery(gpu, geometry)
    assert query.geometry_buffers[0].size == geometry.node_count(orderings=1) * 32
    geometry.write_frame(gpu, query.geometry_buffers, 3)
    origins, dirs = _random_rays(np.random.default_rng(6), 1500)
    _check_against_brute_force(query, geometry.world_triangles(3), origins, dirs)


@pytest.mark.parametrize("module", MODULES)
def test_rays_along_instance_box_faces(gpu, module):
    """Rays that graze a moved instance's world box (along its faces, just inside and just outside)
    find what brute force finds."""
    _require(gpu, module)
    scene = moving_scene(seed=9)
    geometry = InstancedGeometry(scene, frame=2)
    world = geometry.world_triangles(2)
    mover = world[geometry.instance_ids == 1].reshape(-1, 3)
    lo, hi = mover.min(axis=0), mover.max(axis=0)
    rng = np.random.default_rng(4)
    count = 600
    # Along x, at y on (or a hair inside/outside) the box's faces, z across the box.
    y = rng.choice([lo[1], hi[1], lo[1] + 1e-4, hi[1] - 1e-4, lo[1] - 1e-4, hi[1] + 1e-4], count)
    z = rng.uniform(lo[2], hi[2], count)
    origins = np.stack([np.full(count, lo[0] - 1.0), y, z], axis=1)
    dirs = np.tile([1.0, 0.0, 0.0], (count, 1)) + rng.normal(0, 1e-3, (count, 3))
    query = RayQuery(gpu, geometry, traversal=module)
    hits, _ = query.intersect(query_rays(origins, dirs))
    t_ref, prim_ref, ambiguous = brute_force(world, origins, dirs)
    clear = ~ambiguous
    assert clear.mean() > 0.9 and np.sum(prim_ref[clear] >= 0) > 20
    np.testing.assert_array_equal(hits["prim"][clear], np.where(prim_ref >= 0, prim_ref, NO_HIT)[clear])


@pytest.mark.parametrize("module", MODULES)
def test_vertex_normals_come_back_in_world_space(gpu, module):
    """A sphere with vertex normals, rotated, scaled and moved: its interpolated shading normals through
    the instance match those of its world-space copy (single level)."""
    _require(gpu, module)
    vertices, faces, normals = primitive("sphere")
    sphere = Mesh("sphere", vertices, faces, "grey", normals=normals)
    sphere.keyframes = {0: compose(translate([0.2, -0.1, 0.3]), rotate([1, 2, 0], 70), scale(0.8)),
                        1: compose(translate([-0.3, 0.2, 0.0]), rotate([0, 1, 2], -50), scale(1.1))}
    scene = Scene(Camera([0, 0, 5], [0, 0, 0]), [sphere], {"grey": Material()})
    rng = np.random.default_rng(8)
    origins = rng.normal(0, 1, (500, 3))
    origins *= 3 / np.linalg.norm(origins, axis=1, keepdims=True)
    rays = query_rays(origins, rng.uniform(-0.5, 0.5, (500, 3)) - origins)
    for frame in (0, 1):
        instanced = RayQuery(gpu, InstancedGeometry(scene, frame), traversal=module).intersect(rays)[1]
        flat = RayQuery(gpu, GeometryBuffers.build(scene, frame), traversal=module).intersect(rays)[1]
        hit = flat["material"] != NO_HIT
        assert hit.sum() > 100 and np.array_equal(instanced["material"] != NO_HIT, hit)
        np.testing.assert_allclose(instanced["shading_normal"][hit], flat["shading_normal"][hit], atol=1e-4)
        np.testing.assert_allclose(instanced["geometric_normal"][hit], flat["geometric_normal"][hit], atol=1e-4)


def test_world_triangles_match_a_full_rebuild():
    """InstancedGeometry's triangles, mapped to a frame, are the single-level geometry's (as sets)."""
    scene = moving_scene()
    geometry = InstancedGeometry(scene, 0)
    for frame in range(FRAMES):
        flat = GeometryBuffers.build(scene, frame)
        for ours, theirs in ((geometry.world_triangles(frame), flat.triangles),
                             (geometry.object_ids, flat.object_ids)):
            rows = lambda a: a.reshape(len(a), -1)[np.lexsort(a.reshape(len(a), -1).T)]   # noqa: E731
            np.testing.assert_allclose(rows(ours), rows(theirs), atol=1e-5)


def test_suits_only_scenes_with_moving_meshes_and_still_emitters():
    scene = moving_scene()
    assert InstancedGeometry.suits(scene)
    still = Scene(scene.camera, scene.meshes[:2], scene.materials)
    assert not InstancedGeometry.suits(still)
    scene.materials["lamp"] = Material(emission=(1.0, 1.0, 1.0))
    scene.meshes[-1].material = "lamp"
    assert InstancedGeometry.moves_emitters(scene) and not InstancedGeometry.suits(scene)


def _trace_frame(gpu, scene, geometry, frame, module, move_to=None, size=(32, 24), spp=4):
    """The planes of one traced frame; ``move_to``: build at the geometry's frame, then set_frame."""
    trace = TracePass(gpu, scene, geometry, *size, frame=frame if move_to is None else geometry.frame,
                      max_depth=3, seed=7, traversal=module)
    if move_to is not None:
        trace.set_frame(scene, move_to, seed=7)
    buffers = FrameBuffers(gpu, *size)
    encoder = gpu.device.create_command_encoder()
    trace.clear(encoder, buffers)
    trace.execute(encoder, buffers, SampleSchedule(samples=spp))
    gpu.device.queue.submit([encoder.finish()])
    return {name: buffers.read(name) for name in ("radiance", "normal", "depth", "motion")}


@pytest.mark.parametrize("module", MODULES)
@pytest.mark.parametrize("frame", [5, 15])
def test_moving_scene_renders_as_a_full_rebuild(gpu, frame, module):
    """A frame of `moving` traced through the two-level geometry, built at frame 0 and moved to the
    frame, matches the frame traced through a BVH rebuilt for it: same G-buffer and motion vectors,
    same radiance up to the few paths that rounding sends another way."""
    _require(gpu, module)
    scene = load_scene("moving")
    rebuilt = _trace_frame(gpu, scene, GeometryBuffers.build(scene, frame), frame, module)
    moved = _trace_frame(gpu, scene, InstancedGeometry(scene, 0), frame, module, move_to=frame)
    for name in ("normal", "depth", "motion"):
        close = np.all(np.isclose(moved[name], rebuilt[name], atol=1e-3), axis=0)
        assert close.mean() > 0.99, name
    difference = np.abs(moved["radiance"] - rebuilt["radiance"])
    assert np.mean(difference) < 0.01 * np.mean(rebuilt["radiance"])
    assert np.mean(np.all(difference < 1e-3, axis=0)) > 0.95


def test_a_moving_frame_uploads_only_the_top_level(gpu, monkeypatch):
    """After the first frame, a frame of a moving scene writes its parameters and the geometry's
    per-frame arrays (top-level nodes, object motion, instance records) and creates no buffer."""
    scene = load_scene("moving")
    pipeline = Renderer(scene, size=(16, 16), ctx=gpu, aovs=(), max_depth=2).pipeline
    pipeline.render(scene, 0)
    pipeline.render(scene, 1)      # objects moved: the two-level pass is set up
    written = []
    queue_type = type(gpu.device.queue)
    write_buffer = queue_type.write_buffer
    monkeypatch.setattr(queue_type, "write_buffer",
                        lambda queue, buffer, offset, data, *args: written.append(len(memoryview(data).cast("B")))
                        or write_buffer(queue, buffer, offset, data, *args))
    counter = TrafficCounter(monkeypatch, gpu)
    for frame in (2, 3, 4):
        pipeline.render(scene, frame)
    monkeypatch.undo()
    assert counter.uploads == len(written) == 3 * 4      # parameters + nodes, motion, instances
    per_frame = [array.nbytes for array in InstancedGeometry(scene, 0).frame_arrays(1)]
    assert sum(per_frame) < 2048
    assert sorted(set(written)) == sorted({FRAME_PARAMS_DTYPE.itemsize, *per_frame})
    assert sum(written) == 3 * (FRAME_PARAMS_DTYPE.itemsize + sum(per_frame))


def test_a_render_switches_to_two_levels_when_objects_move(gpu):
    """The renderer's first pass keeps the single-level BVH (a single frame traces faster on it); the
    first frame whose objects moved gets a two-level pass, which every later frame reuses."""
    trace_for = Renderer(load_scene("moving"), size=(8, 8), ctx=gpu, aovs=())._trace_factory()
    first = trace_for(0, 0)
    assert isinstance(first._geometry, GeometryBuffers)
    moved = trace_for(1, 1)
    assert isinstance(moved._geometry, InstancedGeometry)
    assert trace_for(2, 2) is moved and trace_for(0, 0) is moved
    still = Renderer(still_moving_scene(), size=(8, 8), ctx=gpu, aovs=())._trace_factory()
    assert isinstance(still(0, 0)._geometry, GeometryBuffers) and still(1, 1) is still(0, 0)


def still_moving_scene():
    """`moving` with its box held still (the camera still moves)."""
    scene = load_scene("moving")
    for mesh in scene.meshes:
        mesh.keyframes = {}
    return scene
