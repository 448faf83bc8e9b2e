"""Two-level geometry (wgpu_rt.accel.geometry.InstancedGeometry, wgsl/accel/instances.wgsl): moving
meshes and shapes placed many times (instances sharing their arrays) as bottom-level BVHs built once,
under a top level rebuilt per frame."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from test_bvh import brute_force
from test_pipeline import TrafficCounter
from test_traversal import MODULES, WALKS, _require

from wgpu_rt.accel.bvh import build_bvh
from wgpu_rt.accel.geometry import GeometryBuffers, InstancedGeometry
from wgpu_rt.accel.ray_query import NO_HIT, RayQuery, query_rays
from wgpu_rt.passes import FrameBuffers
from wgpu_rt import renderer
from wgpu_rt.renderer import Renderer
from wgpu_rt.scene import Camera, Material, Mesh, Scene, load_scene
from wgpu_rt.scene.primitives import primitive
from wgpu_rt.scene.transforms import compose, rotate, scale, translate
from wgpu_rt.trace import SampleSchedule, TracePass
from wgpu_rt.trace import scene_data
from wgpu_rt.trace.scene_data import FRAME_PARAMS_DTYPE


@pytest.fixture(autouse=True)
def two_levels_for_every_instanced_scene(monkeypatch):
    """These tests are of the two-level path: the renderer takes it for any still scene with instances
    (by default it flattens small ones, which the threshold's own test checks)."""
    monkeypatch.setattr(renderer, "FLATTEN_PLACED_TRIANGLES", 0)


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


def placed_scene(seed: int = 5) -> Scene:
    """A static soup placed once (the world-space level), a soup shape placed 12 times (rotated, scaled
    non-uniformly, one mirrored, every third in another material, one moving) and a moving soup."""
    rng = np.random.default_rng(seed)
    floor = _mesh("floor", _soup(rng, 6, 20, 0.1))
    shape = _mesh("shape", _soup(rng, 4, 15, 0.15))
    placements = []
    for i in range(12):
        factors = rng.uniform(0.4, 0.9, 3) * [-1 if i == 4 else 1, 1, 1]
        placements.append(shape.instance(f"shape[{i}]", "red" if i % 3 == 0 else None, compose(
            translate(rng.uniform(-1.2, 1.2, 3)), rotate(rng.normal(size=3), rng.uniform(0, 360)), scale(factors))))
    placements[7].keyframes = {f: compose(translate([0.2 * f, -0.1 * f, 0]), placements[7].transform)
                               for f in range(FRAMES)}
    mover = _mesh("mover", _soup(rng, 3, 20, 0.1))
    mover.keyframes = {f: compose(translate([0, 0.3 * f, 0]), rotate([1, 1, 0], 20 * f)) for f in range(FRAMES)}
    scene = Scene(Camera([0, 0, 5], [0, 0, 0]), [floor, *placements, mover],
                  {"grey": Material(), "red": Material(reflectance=(0.8, 0.1, 0.1))})
    scene.frame_count = FRAMES
    return scene


def copied(scene: Scene) -> Scene:
    """``scene`` written out without instances: every mesh with arrays of its own."""
    return dataclasses.replace(scene, meshes=[
        Mesh(m.name, m.vertices.copy(), m.faces.copy(), m.material, None if m.normals is None else m.normals.copy(),
             m.transform.copy(), dict(m.keyframes)) for m in scene.meshes])


def _random_rays(rng, count: int):
    origins = rng.uniform(-2.5, 2.5, (count, 3))
    targets = rng.uniform(-1.5, 1.5, (count, 3))
    return origins, targets - origins


def _check_against_brute_force(query: RayQuery, world: np.ndarray, origins, dirs, geometry=None):
    """Hits, distances, occlusion and world normals of the rays as brute force finds them in ``world``
    (the placed triangles by number); with ``geometry``, each hit's material and object as its ids say."""
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
        if geometry is not None:
            np.testing.assert_array_equal(surfaces["material"][found], geometry.material_ids[prim_ref[found]])
            np.testing.assert_array_equal(surfaces["object"][found], geometry.object_ids[prim_ref[found]])


@pytest.mark.parametrize("module, variant", WALKS)
def test_instanced_traversal_matches_brute_force(gpu, module, variant):
    """Closest hits, occlusion and world-space normals through static and moving instances, at the
    frame the geometry was built for and after moving it to other frames (per-frame buffers only), with
    the bottom levels walked in each layout."""
    _require(gpu, module)
    scene = moving_scene()
    geometry = InstancedGeometry(scene, frame=1).as_variant(variant)
    assert len(geometry.levels) == 4           # the static meshes share one bottom level
    query = RayQuery(gpu, geometry, traversal=module)
    rng = np.random.default_rng(3)
    for frame in (1, 3, 0):
        if frame != geometry.frame:
            geometry.write_frame(gpu, query.geometry_buffers, frame)
        origins, dirs = _random_rays(rng, 1500)
        _check_against_brute_force(query, geometry.world_triangles(frame), origins, dirs)


@pytest.mark.parametrize("module, variant", WALKS)
def test_instances_of_a_shape_traverse_like_brute_force(gpu, module, variant):
    """A shape placed 12 times (one bottom level) between a world-space level and a moving mesh: hits
    number the placed triangles, and each comes back with its instance's material and object, at the
    frame built and after moving to others, with the bottom levels walked in each layout."""
    _require(gpu, module)
    scene = placed_scene()
    geometry = InstancedGeometry(scene, frame=1).as_variant(variant)
    assert [len(meshes) for meshes, _ in geometry.levels] == [1, 1, 1]     # floor, the shape, the mover
    assert len(geometry.instance_meshes) == 1 + 12 + 1
    assert geometry.triangle_count == 120 + 60 + 60 and geometry.placed_triangle_count == 120 + 12 * 60 + 60
    query = RayQuery(gpu, geometry, traversal=module)
    rng = np.random.default_rng(12)
    for frame in (1, 3):
        if frame != geometry.frame:
            geometry.write_frame(gpu, query.geometry_buffers, frame)
        origins, dirs = _random_rays(rng, 1500)
        _check_against_brute_force(query, geometry.world_triangles(frame), origins, dirs, geometry)


# Asks accel/bvh.wgsl about triangles by number, with no walk before (so each invocation finds the
# instance of its number by search, not from a remembered hit): material, object, world vertices.
TRIANGLE_QUERY = """
@group(1) @binding(0) var<storage, read> numbers: array<u32>;
@group(1) @binding(1) var<storage, read_write> found: array<array<u32, 12>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3u, @builtin(local_invocation_index) local_index: u32) {
    begin_traversal(local_index);
    if id.x >= arrayLength(&numbers) { return; }
    let prim = numbers[id.x];
    let p = tri_vertices(prim);
    found[id.x] = array<u32, 12>(tri_material(prim), tri_object(prim), 0u,
                                 bitcast<u32>(p[0].x), bitcast<u32>(p[0].y), bitcast<u32>(p[0].z),
                                 bitcast<u32>(p[1].x), bitcast<u32>(p[1].y), bitcast<u32>(p[1].z),
                                 bitcast<u32>(p[2].x), bitcast<u32>(p[2].y), bitcast<u32>(p[2].z));
}
"""


def test_every_placed_triangle_is_found_by_its_number(gpu):
    """tri_material, tri_object and tri_vertices of every placed triangle number, in shuffled order,
    match the geometry's ids and world triangles: the instance search covers every instance."""
    from wgpu_rt.accel.geometry import NO_INSTANCES, compose_with_traversal

    scene = placed_scene()
    geometry = InstancedGeometry(scene, frame=2)
    code = compose_with_traversal(gpu, "accel/bvh.wgsl", replacements={NO_INSTANCES: geometry.instances_module})
    pipeline = gpu.compute_pipeline(code + TRIANGLE_QUERY, label="triangle query")
    numbers = np.random.default_rng(1).permutation(geometry.placed_triangle_count).astype(np.uint32)
    geometry_buffers = [None if i in (0, 3) else b for i, b in enumerate(geometry.upload(gpu))]   # unread
    found = gpu.storage(48 * len(numbers))
    encoder = gpu.device.create_command_encoder()
    compute = encoder.begin_compute_pass()
    compute.set_pipeline(pipeline)
    compute.set_bind_group(0, gpu.bind_group(pipeline, geometry_buffers, group=0))
    compute.set_bind_group(1, gpu.bind_group(pipeline, [gpu.upload(numbers), found], group=1))
    compute.dispatch_workgroups(-(-len(numbers) // 64))
    compute.end()
    gpu.device.queue.submit([encoder.finish()])
    words = gpu.read(found, np.uint32).reshape(-1, 12)
    np.testing.assert_array_equal(words[:, 0], geometry.material_ids[numbers])
    np.testing.assert_array_equal(words[:, 1], geometry.object_ids[numbers])
    np.testing.assert_allclose(words[:, 3:].view(np.float32).reshape(-1, 3, 3),
                               geometry.world_triangles(2)[numbers], atol=1e-5)


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
@pytest.mark.parametrize("instances", [1, 3])
def test_vertex_normals_come_back_in_world_space(gpu, module, instances):
    """A sphere with vertex normals, rotated, scaled and moved (placed once, or three times: one moving,
    one mirrored, one in another material): its interpolated shading normals, materials and objects
    through the instances match those of its world-space copies (single level)."""
    _require(gpu, module)
    vertices, faces, normals = primitive("sphere")
    sphere = Mesh("sphere", vertices, faces, "grey", normals=normals)
    sphere.keyframes = {0: compose(translate([0.2, -0.1, 0.3]), rotate([1, 2, 0], 70), scale(0.8)),
                        1: compose(translate([-0.3, 0.2, 0.0]), rotate([0, 1, 2], -50), scale(1.1))}
    others = [sphere.instance("mirrored", transform=compose(translate([1.2, 0.6, 0]), scale([-0.5, 0.5, 0.4]))),
              sphere.instance("red", "red", compose(translate([-1.1, -0.7, 0.2]), scale(0.4)))]
    scene = Scene(Camera([0, 0, 5], [0, 0, 0]), [sphere, *others[:instances - 1]],
                  {"grey": Material(), "red": Material(reflectance=(0.8, 0.1, 0.1))})
    rng = np.random.default_rng(8)
    origins = rng.normal(0, 1, (500, 3))
    origins *= 3 / np.linalg.norm(origins, axis=1, keepdims=True)
    rays = query_rays(origins, rng.uniform(-1.2, 1.2, (500, 3)) - origins)
    for frame in (0, 1):
        instanced = RayQuery(gpu, InstancedGeometry(scene, frame), traversal=module).intersect(rays)[1]
        flat = RayQuery(gpu, GeometryBuffers.build(scene, frame), traversal=module).intersect(rays)[1]
        hit = flat["material"] != NO_HIT
        assert hit.sum() > 100 and np.array_equal(instanced["material"] != NO_HIT, hit)
        # Barycentrics found in object space round differently: on the small spheres' small triangles
        # the interpolated normals agree to 2e-4.
        np.testing.assert_allclose(instanced["shading_normal"][hit], flat["shading_normal"][hit], atol=5e-4)
        np.testing.assert_allclose(instanced["geometric_normal"][hit], flat["geometric_normal"][hit], atol=1e-4)
        for name in ("material", "object"):
            np.testing.assert_array_equal(instanced[name], flat[name])
        assert len(np.unique(flat["object"][hit])) == instances


@pytest.mark.parametrize("make_scene", [moving_scene, placed_scene])
def test_world_triangles_match_a_full_rebuild(make_scene):
    """InstancedGeometry's placed triangles, mapped to a frame, with their materials and objects, are
    the single-level geometry's (as sets of rows)."""
    scene = make_scene()
    geometry = InstancedGeometry(scene, 0)
    def rows(table):
        return table[np.lexsort(table.T)]

    for frame in range(FRAMES):
        flat = GeometryBuffers.build(scene, frame)
        ours, theirs = ([triangles.reshape(len(triangles), -1), materials[:, None], objects[:, None]]
                        for triangles, materials, objects in (
                            (geometry.world_triangles(frame), geometry.material_ids, geometry.object_ids),
                            (flat.triangles, flat.material_ids, flat.object_ids)))
        np.testing.assert_allclose(rows(np.hstack(ours)), rows(np.hstack(theirs)), atol=1e-5)


def test_a_shape_placed_many_times_is_stored_once(monkeypatch):
    """200 placements of a 60-triangle shape next to a 120-triangle floor: two BVH builds (the shape's,
    the floor's), each over its own triangles, and buffers that hold the shape's triangles and nodes
    once plus two entry nodes and one record per instance, where the flattened scene holds 200 copies."""
    import wgpu_rt.accel.geometry as geometry_module

    rng = np.random.default_rng(2)
    floor, shape = _mesh("floor", _soup(rng, 6, 20, 0.1)), _mesh("shape", _soup(rng, 4, 15, 0.1))
    placements = [shape.instance(f"shape[{i}]", transform=translate([i % 20, 0, i // 20])) for i in range(200)]
    scene = Scene(Camera([0, 0, 5], [0, 0, 0]), [floor, *placements], {"grey": Material()})
    built = []
    monkeypatch.setattr(geometry_module, "build_bvh",
                        lambda triangles, *cost: built.append(len(triangles)) or build_bvh(triangles, *cost))
    geometry = InstancedGeometry(scene)
    assert sorted(built) == [60, 120]
    nodes, positions, attributes, motion, records = geometry.packed_arrays()
    shape_nodes, floor_nodes = (build_bvh(m.vertices[m.faces]).node_count for m in (shape, floor))
    assert len(nodes) == 8 * (2 * 201 - 1) + 2 * 201 + 8 * (shape_nodes + floor_nodes)
    assert len(positions) == len(attributes) == 180 and len(records) == 201 and len(motion) == 201
    built.clear()
    flat_positions = GeometryBuffers.build(copied(scene)).packed_arrays()[1]
    assert built == [120 + 200 * 60] and len(flat_positions) == 120 + 200 * 60
    assert geometry.placed_triangle_count == len(flat_positions)


def test_static_instances_get_two_levels_from_the_first_frame(gpu, monkeypatch):
    """The renderer traces a still scene with instances through the two-level geometry from its first
    frame on (reused by every frame) when it places more than FLATTEN_PLACED_TRIANGLES, else through a
    single level, as it does the same scene with copied meshes; and a scene with instances and a moving
    emitter through one two-level pass that follows it."""
    scene = still_instanced_scene()
    placed = sum(len(mesh.faces) for mesh in scene.meshes)
    monkeypatch.setattr(renderer, "FLATTEN_PLACED_TRIANGLES", placed)
    assert isinstance(Renderer(scene, size=(8, 8), ctx=gpu, aovs=())._trace_factory()(0, 0)._geometry,
                      GeometryBuffers)
    monkeypatch.setattr(renderer, "FLATTEN_PLACED_TRIANGLES", placed - 1)
    trace_for = Renderer(scene, size=(8, 8), ctx=gpu, aovs=())._trace_factory()
    first = trace_for(0, 0)
    assert isinstance(first._geometry, InstancedGeometry) and trace_for(1, 1) is first
    flat = Renderer(copied(scene), size=(8, 8), ctx=gpu, aovs=())._trace_factory()
    assert isinstance(flat(0, 0)._geometry, GeometryBuffers)
    lamp = next(m for m in scene.meshes if m.material == "lamp")
    lamp.keyframes = {0: lamp.transform, 1: compose(translate([0.1, 0, 0]), lamp.transform)}
    moving_lamp = Renderer(scene, size=(8, 8), ctx=gpu, aovs=())._trace_factory()
    first = moving_lamp(0, 0)
    assert isinstance(first._geometry, InstancedGeometry) and moving_lamp(1, 1) is first


def still_instanced_scene() -> Scene:
    """A floor, a cube placed 9 times in three materials, and a lamp placed 3 times (its emitter table
    covers every placement)."""
    floor = Mesh("floor", *primitive("rectangle")[:2], "grey", transform=compose(rotate([1, 0, 0], -90), scale(3)))
    lamp, cube = Mesh("lamp", *primitive("rectangle")[:2], "lamp"), Mesh("cube", *primitive("cube")[:2], "grey")
    cubes = [cube.instance(f"cube[{i}]", ("grey", "red", "gold")[i % 3],
                           compose(translate([i % 3 - 1, 0.25, i // 3 - 1]), rotate([0, 1, 0], 20 * i), scale(0.25)))
             for i in range(9)]
    lamps = [lamp.instance(f"lamp[{i}]", transform=compose(translate([i - 1, 1.5, 0]), rotate([1, 0, 0], 90),
                                                            scale(0.2))) for i in range(3)]
    materials = {"grey": Material(), "red": Material(reflectance=(0.8, 0.1, 0.1)),
                 "gold": Material("conductor", roughness=0.3, eta=(0.14, 0.37, 1.44), k=(3.98, 2.39, 1.6)),
                 "lamp": Material(emission=(6.0, 5.0, 4.0))}
    return Scene(Camera([0.3, 1.8, 3.5], [0, 0.2, 0]), [floor, *cubes, *lamps], materials,
                 background=np.array([0.05, 0.05, 0.08], np.float32))


def _render(gpu, scene, seed: int, spp: int, size=(32, 24)):
    return next(Renderer(scene, spp=spp, size=size, ctx=gpu, max_depth=4, seed=seed,
                         aovs=("normal", "depth", "albedo")).frames())


def test_an_instanced_scene_renders_as_its_copy(gpu):
    """examples/forest.toml (a tree mesh placed 53 times in three materials, a sphere placed 10 times)
    renders as the same scene written out with copied meshes at the same seed: the same G-buffer, the
    same colour up to float rounding."""
    scene = load_scene(Path(__file__).resolve().parents[1] / "examples" / "forest.toml")
    instanced, flat = _render(gpu, scene, 4, 4), _render(gpu, copied(scene), 4, 4)
    for name in ("normal", "depth", "albedo"):
        close = np.all(np.isclose(instanced.aovs[name], flat.aovs[name], atol=1e-3), axis=-1)
        assert close.mean() > 0.99, name
    difference = np.abs(instanced.color - flat.color)
    assert np.mean(difference) < 1e-3 * np.mean(flat.color)
    assert np.mean(np.all(difference < 1e-3, axis=-1)) > 0.98


def test_instanced_lamps_render_as_their_copies_within_noise(gpu):
    """A lamp placed three times lights the scene as three copied lamps do: the emitter tables hold the
    same triangles, numbered differently (placed order, BVH order), so at one seed the images may differ
    by noise, but by no more than two seeds of the copied scene differ."""
    scene = still_instanced_scene()
    instanced = _render(gpu, scene, 1, 64).color
    flat, flat_again = (_render(gpu, copied(scene), seed, 64).color for seed in (1, 2))
    noise = np.mean(np.abs(flat - flat_again))
    assert np.mean(np.abs(instanced - flat)) < 1.5 * noise
    np.testing.assert_allclose(instanced.mean(axis=(0, 1)), flat.mean(axis=(0, 1)), rtol=0.02)


def test_suits_only_scenes_with_moving_meshes_or_instances_and_still_emitters():
    scene = moving_scene()
    assert InstancedGeometry.suits(scene)
    still = Scene(scene.camera, scene.meshes[:2], scene.materials)
    assert not InstancedGeometry.suits(still)
    still.meshes.append(still.meshes[0].instance("again", transform=translate([1, 0, 0])))
    assert InstancedGeometry.suits(still)
    scene.materials["lamp"] = Material(emission=(1.0, 1.0, 1.0))
    scene.meshes[-1].material = "lamp"
    assert InstancedGeometry.moves_emitters(scene) and InstancedGeometry.suits(scene)


def lamp_scene() -> Scene:
    """`moving` with its light panel swinging across the ceiling, the small box moving as before."""
    scene = load_scene("moving")
    light = next(m for m in scene.meshes if scene.materials[m.material].is_emissive)
    for frame in range(scene.frame_count):
        light.keyframes[frame] = compose(translate([0.4 * np.sin(frame), -0.05 * frame / scene.frame_count, 0.2]),
                                         rotate([0, 1, 0], 20 * frame), light.transform)
    return scene


@pytest.mark.parametrize("frame", [6, 13])
def test_a_moving_light_is_followed_without_a_rebuild(gpu, frame):
    """A frame traced through the two-level geometry built at frame 0 and moved to ``frame``, emitter
    table included, matches the frame traced through a BVH and emitter table built for it."""
    scene = lamp_scene()
    assert InstancedGeometry.moves_emitters(scene)
    rebuilt = _trace_frame(gpu, scene, GeometryBuffers.build(scene, frame), frame, None)
    moved = _trace_frame(gpu, scene, InstancedGeometry(scene, 0), frame, None, move_to=frame)
    stale = _trace_frame(gpu, scene, GeometryBuffers.build(scene, 0), 0, None)
    difference = np.abs(moved["radiance"] - rebuilt["radiance"])
    assert np.mean(difference) < 0.01 * np.mean(rebuilt["radiance"])
    assert np.mean(np.all(difference < 1e-3, axis=0)) > 0.95
    # the light really moved: the frame's lighting differs from frame 0's far beyond that
    assert np.mean(np.abs(stale["radiance"] - rebuilt["radiance"])) > 10 * np.mean(difference)


def test_a_moving_light_changes_its_cluster_without_a_rebuild(gpu, monkeypatch):
    """Four point lights in a row beside the swinging panel and room for 3 emitter groups: the clusters
    in space change as the panel swings (between frames 6 and 13 it leaves one pair of point lights for
    the other), and the moved pass follows: its records, their order and the triangles' entries."""
    from wgpu_rt.scene import PointLight

    monkeypatch.setattr(scene_data, "MAX_EMITTER_GROUPS", 3)
    scene = lamp_scene()
    scene.lights = [PointLight(np.float32([x, 0.5, 0.3]), np.float32([0.05, 0.05, 0.05]))
                    for x in (-0.45, -0.3, 0.3, 0.45)]
    trace = TracePass(gpu, scene, InstancedGeometry(scene, 0), 32, 24, frame=6)
    entries = lambda: np.frombuffer(gpu.device.queue.read_buffer(trace._triangle_entry), np.uint32).copy()  # noqa: E731
    before = entries()
    trace.set_frame(scene, 13, 0)
    assert np.any(entries() != before), "the panel's records should move with its cluster"
    built_there = TracePass(gpu, scene, InstancedGeometry(scene, 13), 32, 24, frame=13)
    np.testing.assert_array_equal(entries(), built_there._emitter_table.triangle_entry)
    rebuilt = _trace_frame(gpu, scene, GeometryBuffers.build(scene, 13), 13, None, spp=16)
    moved = _trace_frame(gpu, scene, InstancedGeometry(scene, 6), 13, None, move_to=13, spp=16)
    difference = np.abs(moved["radiance"] - rebuilt["radiance"])
    assert np.mean(difference) < 0.01 * np.mean(rebuilt["radiance"])


def test_a_moving_light_renders_frames_in_place(gpu):
    """Through the renderer: the frames of a scene with a moving light after the first reuse one
    two-level pass, and each equals a render of that frame alone (same seed)."""
    scene = lamp_scene()
    renderer = Renderer(scene, spp=2, size=(24, 16), ctx=gpu, aovs=(), max_depth=3)
    frames = list(renderer.frames([0, 1, 2]))
    alone = next(iter(Renderer(scene, spp=2, size=(24, 16), ctx=gpu, aovs=(), max_depth=3).frames([2])))
    assert np.isfinite(frames[2].color).all()
    assert np.mean(np.abs(frames[2].color - alone.color)) < 0.02 * np.mean(alone.color)


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


def test_two_levels_walk_as_the_adapter_or_the_environment_says(gpu, monkeypatch):
    """Two-level geometry is not measured (its top level changes every frame): the bottom levels of a
    scene too small to be measured take the adapter's unmeasured pick (the 4-wide walk on GPUs, the
    threaded one on lavapipe), or the variant WGPU_RT_BVH names."""
    from wgpu_rt.accel.geometry import BVH_LAYOUT_ENV, traversal_module
    from wgpu_rt.trace.bvh_choice import unmeasured_layout

    def moved_variant():
        return Renderer(load_scene("moving"), size=(8, 8), ctx=gpu, aovs=())._trace_factory()(1, 1)._geometry.variant

    monkeypatch.delenv(BVH_LAYOUT_ENV, raising=False)
    assert moved_variant() == unmeasured_layout(gpu, traversal_module(gpu))
    monkeypatch.setenv(BVH_LAYOUT_ENV, "wide")
    assert moved_variant() == "wide"


def test_a_mesh_that_starts_to_move_keeps_the_measured_walk(gpu, monkeypatch, tmp_path):
    """A scene big enough to be measured traces its first frame single-level with the measured variant
    (here the cache's: small leaves); once its mesh moves, the bottom levels keep that variant, small
    leaves included."""
    import trimesh

    from test_bvh_choice import fake_timer

    from wgpu_rt.accel.geometry import BVH_LAYOUT_ENV
    from wgpu_rt.measured_choices import CACHE_DIR_ENV, MeasuredChoices
    from wgpu_rt.trace.bvh_choice import choose_layout

    path = tmp_path / "sphere.obj"
    trimesh.creation.icosphere(subdivisions=4).export(path)
    scene = load_scene("mesh", mesh=path)
    monkeypatch.setenv(CACHE_DIR_ENV, str(tmp_path))
    monkeypatch.delenv(BVH_LAYOUT_ENV, raising=False)
    small = "wide+small-leaves"
    choices = MeasuredChoices(gpu, timer=fake_timer({"threaded": 2.0, "wide": 1.5, small: 1.0}, []))
    assert choose_layout(gpu, scene, GeometryBuffers.build(scene), choices=choices).variant == small
    sphere = scene.meshes[-1]
    scene.frame_count = 2
    sphere.keyframes = {0: sphere.transform, 1: compose(translate([0.1, 0, 0]), sphere.transform)}
    trace_for = Renderer(scene, size=(8, 8), ctx=gpu, aovs=())._trace_factory()
    assert trace_for(0, 0)._geometry.variant == small
    moved = trace_for(1, 1)._geometry
    assert isinstance(moved, InstancedGeometry) and moved.variant == small and moved.small_leaves


def still_moving_scene():
    """`moving` with its box held still (the camera still moves)."""
    scene = load_scene("moving")
    for mesh in scene.meshes:
        mesh.keyframes = {}
    return scene


def test_mitsuba_export_places_every_instance(gpu, mi):
    """to_mitsuba writes each instance out as a mesh of its own, exactly as for the copied scene, and
    Mitsuba renders the instanced scene (lamps, gold and coloured cubes) as our two-level tracer does."""
    from wgpu_rt.scene.mitsuba import to_mitsuba

    scene, size = still_instanced_scene(), (24, 24)
    exported, exported_copy = (to_mitsuba(s, *size, 256, max_depth=4) for s in (scene, copied(scene)))
    keys = [key for key in exported if key.startswith("mesh")]
    assert len(keys) == len(scene.meshes) and keys == [key for key in exported_copy if key.startswith("mesh")]
    for key in keys:
        ours, theirs = (np.array(mi.traverse(d[key])["vertex_positions"]) for d in (exported, exported_copy))
        np.testing.assert_array_equal(ours, theirs)
    reference = np.array(mi.render(mi.load_dict(exported), spp=256))[..., :3]
    traced = _render(gpu, scene, 0, 128, size).color
    ratio = traced.reshape(-1, 3).mean(0) / reference.reshape(-1, 3).mean(0)
    assert np.all(np.abs(ratio - 1) < 0.03), ratio


def test_dataset_variations_keep_instances():
    """A dataset variation of a scene with instances (a deep copy with objects, materials and camera
    changed) keeps its instances sharing their arrays, and flattens to the same triangles as it."""
    from wgpu_rt.dataset.variety import scene_bounds, vary_scene

    scene = still_instanced_scene()
    varied = vary_scene(scene, np.random.default_rng(3), frames=2)
    assert [group for group in varied.shapes() if len(group) > 1] == [list(range(1, 10)), [10, 11, 12]]
    geometry, flat = InstancedGeometry(varied, 1), GeometryBuffers.build(varied, 1)
    assert geometry.placed_triangle_count == flat.triangle_count
    assert flat.triangle_count - geometry.triangle_count == 8 * 12 + 2 * 2    # the copies not stored
    assert np.all(np.isfinite(scene_bounds(varied, 1)))


@pytest.mark.parametrize("frame", [0, 3])
def test_placed_triangles_are_the_world_triangles_they_number(frame):
    """placed_triangles (a moving light's per-frame emitter table asks only for its triangles) gives,
    for numbers in any order, what world_triangles gives for the whole scene."""
    geometry = InstancedGeometry(placed_scene(), 0)
    numbers = np.random.default_rng(frame).permutation(geometry.placed_triangle_count)[:500]
    # both map in float64 and round to float32 once (the products may be summed in another order)
    np.testing.assert_allclose(geometry.placed_triangles(frame, numbers), geometry.world_triangles(frame)[numbers],
                               rtol=1e-6, atol=1e-6)
