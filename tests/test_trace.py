"""The tracer's sampling contract: reproducible from the seed, extra passes add distinct samples and
keep the running means consistent, the alias table picks emitters in proportion to power (a sun's and
a sky's through the region the camera frames), the
G-buffers hold what ARCHITECTURE.md says they hold."""

from pathlib import Path

import numpy as np
import pytest

from wgpu_rt.renderer import render
from wgpu_rt.passes import FrameBuffers
from wgpu_rt.scene import load_scene
from wgpu_rt.scene.loader import parse_scene
from wgpu_rt.accel.geometry import GeometryBuffers
from wgpu_rt.trace import SampleSchedule, TracePass
from wgpu_rt.trace.trace_pass import WorkList, batch_count, item_counts, work_list_entries
from wgpu_rt.trace.scene_data import alias_table, build_emitter_table, view_radius

SIZE = (24, 24)


def test_same_seed_same_bits_other_seed_other_noise(gpu):
    a = render("cornell", spp=4, size=SIZE, seed=7)
    b = render("cornell", spp=4, size=SIZE, seed=7)
    c = render("cornell", spp=4, size=SIZE, seed=8)
    assert a.color.tobytes() == b.color.tobytes()
    assert all(a.aovs[k].tobytes() == b.aovs[k].tobytes() for k in a.aovs)
    assert np.mean(np.abs(a.color - c.color)) > 1e-3


def _trace(gpu, scene_name, counts=None, passes=(4,), batch_items=None, item_samples=3):
    scene = load_scene(scene_name)
    trace = TracePass(gpu, scene, GeometryBuffers.build(scene), *SIZE, chunk_size=3, batch_items=batch_items,
                      item_samples=item_samples)
    buffers = FrameBuffers(gpu, *SIZE)
    encoder = gpu.device.create_command_encoder()
    trace.clear(encoder, buffers)
    for samples in passes:
        trace.execute(encoder, buffers, SampleSchedule(samples))
    if counts is not None:
        trace.execute(encoder, buffers, SampleSchedule(int(counts.max()), gpu.upload(counts.astype(np.uint32)),
                                                       total_samples=int(counts.sum())))
    gpu.device.queue.submit([encoder.finish()])
    return buffers


def test_split_passes_equal_one_pass(gpu):
    """Chunks and passes continue each pixel's sequence: 3 + 5 samples are the 8 samples of one pass."""
    whole = _trace(gpu, "cornell", passes=(8,))
    split = _trace(gpu, "cornell", passes=(3, 5))
    np.testing.assert_allclose(split.read("radiance"), whole.read("radiance"), rtol=1e-5, atol=1e-6)
    assert np.all(split.read("spp") == 8)


@pytest.mark.parametrize("batch_items, item_samples", [(None, 3), (64, 3), (None, None)])
def test_extra_sample_counts_add_distinct_samples(gpu, batch_items, item_samples):
    """A targeted pass (a count per pixel) traces, per pixel, the very samples a uniform pass would add:
    a pixel with 2 + k samples holds a uniform render's mean of its first 2 + k samples in every plane
    that is a mean (the normal plane renormalizes at each fold, so it follows how the samples were
    grouped). Counts up to 10 over items of at most 3 samples split a pixel into up to 4 items; 64 items
    per batch spread a pixel's items over two batches, and a frame over many; the default items hold
    MIN_ITEM_SAMPLES (more than the dispatches' chunk of 3)."""
    rng = np.random.default_rng(1)
    counts = rng.integers(0, 11, size=SIZE[0] * SIZE[1])
    uniform_then_extra = _trace(gpu, "cornell", counts=counts, passes=(2,), batch_items=batch_items,
                                item_samples=item_samples)
    spp = uniform_then_extra.read("spp").ravel()
    np.testing.assert_array_equal(spp, 2 + counts)
    for k in (0, 1, 3, 4, 7, 10):
        reference = _trace(gpu, "cornell", passes=(2 + k,))
        pick = counts == k
        for plane in ("radiance", "albedo", "depth"):
            channels = reference.read(plane).shape[0]
            np.testing.assert_allclose(uniform_then_extra.read(plane).reshape(channels, -1)[:, pick],
                                       reference.read(plane).reshape(channels, -1)[:, pick], rtol=1e-5, atol=1e-6,
                                       err_msg=f"{plane}, pixels with {k} extra samples")


@pytest.mark.parametrize("rows", [1, 2, 3, 8, 17, 135, 2048])
def test_tile_row_stride_visits_every_row_once(rows):
    from wgpu_rt.trace.trace_pass import tile_row_stride

    stride = tile_row_stride(rows)
    assert sorted(y * stride % rows for y in range(rows)) == list(range(rows))
    assert abs(stride - 0.618 * rows) <= max(2, 0.05 * rows)


def test_tile_order_leaves_the_image_as_it_is(gpu, monkeypatch):
    """Tracing tile rows in the scattered order (camera.wgsl's tile_pixel; CPU drivers) gives the image of
    tracing them top to bottom (GPUs), bit for bit, the aux pass's albedo included."""
    from wgpu_rt.trace import trace_pass

    scene = load_scene("cornell-glossy")
    size = (40, 56)   # 7 tile rows: stride 4

    def planes():
        trace = TracePass(gpu, scene, GeometryBuffers.build(scene), *size, max_depth=4)
        buffers = FrameBuffers(gpu, *size)
        encoder = gpu.device.create_command_encoder()
        trace.clear(encoder, buffers)
        trace.execute(encoder, buffers, SampleSchedule(samples=2))
        trace.execute_aux(encoder, buffers)
        gpu.device.queue.submit([encoder.finish()])
        return {plane.name: buffers.read(plane.name) for plane in TracePass.outputs}

    assert trace_pass.tile_row_stride(7) != 1
    monkeypatch.setattr(trace_pass, "scatters_tile_rows", lambda ctx: True)
    scattered = planes()
    monkeypatch.setattr(trace_pass, "scatters_tile_rows", lambda ctx: False)
    in_order = planes()
    for name, plane in in_order.items():
        assert plane.tobytes() == scattered[name].tobytes(), name


def test_work_items_hold_at_least_min_item_samples(gpu):
    """Items of a targeted pass hold the dispatches' chunk of samples, at least MIN_ITEM_SAMPLES (an
    item that takes several regenerates paths; each costs a list search and a slot), and a default batch
    about one uniform dispatch's samples."""
    from wgpu_rt.trace.trace_pass import MIN_ITEM_SAMPLES

    scene = load_scene("cornell")
    geometry = GeometryBuffers.build(scene)
    small_chunks = TracePass(gpu, scene, geometry, *SIZE, chunk_size=1)
    assert small_chunks.item_samples == MIN_ITEM_SAMPLES
    assert small_chunks._batch_items == max(64, SIZE[0] * SIZE[1] // MIN_ITEM_SAMPLES)
    assert TracePass(gpu, scene, geometry, *SIZE, chunk_size=16).item_samples == max(16, MIN_ITEM_SAMPLES)


def test_targeted_pass_is_deterministic_and_skips_pixels_without_samples(gpu):
    """The same counts give the same bits; a pixel with no samples keeps what it held, and an all-zero map
    adds nothing."""
    counts = np.random.default_rng(2).integers(0, 9, size=SIZE[0] * SIZE[1]) * (np.arange(SIZE[0] * SIZE[1]) % 3 > 0)
    first = _trace(gpu, "cornell", counts=counts, passes=(1,), batch_items=128)
    second = _trace(gpu, "cornell", counts=counts, passes=(1,), batch_items=128)
    probe = _trace(gpu, "cornell", passes=(1,))
    nothing = _trace(gpu, "cornell", counts=np.zeros_like(counts), passes=(1,))
    for plane in TracePass.outputs:
        assert first.read(plane.name).tobytes() == second.read(plane.name).tobytes(), plane.name
        assert nothing.read(plane.name).tobytes() == probe.read(plane.name).tobytes(), plane.name
    untouched = (counts == 0)
    assert untouched.any()
    np.testing.assert_array_equal(first.read("radiance").reshape(3, -1)[:, untouched],
                                  probe.read("radiance").reshape(3, -1)[:, untouched])


@pytest.mark.parametrize("size, item_samples", [((24, 24), 3), ((37, 29), 16), ((40, 8), 1), ((3, 17), 3),
                                                ((65, 1), 2)])
def test_work_list_matches_reference(gpu, size, item_samples):
    """The device's compacted list (wgsl/trace/work_list_build.wgsl) is the numpy reference's: the pixels
    with samples in the reference's order, each entry's first item after the items of those before it,
    each entry holding the samples its pixel had before the pass; and each batch dispatches its items,
    and resolves those of pixels of several items."""
    pixels = size[0] * size[1]
    rng = np.random.default_rng(3)
    counts = (rng.integers(0, 40, pixels) * (rng.uniform(size=pixels) < 0.7)).astype(np.uint32)
    spp = rng.integers(0, 100, pixels).astype(np.uint32)
    work = WorkList(gpu, *size, item_samples, batch_items=pixels)
    encoder = gpu.device.create_command_encoder()
    work.record_build(encoder, gpu.upload(counts), gpu.upload(spp), batches=2)
    gpu.device.queue.submit([encoder.finish()])
    expected_pixels, expected_first = work_list_entries(counts, item_samples, size[0])
    items, entries, batch_items, waiting_items, waiting_entries = (
        int(value) for value in gpu.read(work.totals, np.uint32)[:5])
    assert entries == len(expected_pixels) and batch_items == work.batch_items
    assert items == int(item_counts(counts, item_samples).sum())
    listed = gpu.read(work.entries, np.uint32)[:3 * entries].reshape(-1, 3)
    np.testing.assert_array_equal(listed[:, 0], expected_pixels)
    np.testing.assert_array_equal(listed[:, 1], expected_first)
    np.testing.assert_array_equal(listed[:, 2], spp[expected_pixels])
    groups = gpu.read(work.batch_args(2), np.uint32)[:12].reshape(2, 2, 3)   # batch, trace/resolve, xyz
    several = item_counts(counts, item_samples) > 1
    waiting = int(item_counts(counts, item_samples)[several].sum())
    assert (waiting_items, waiting_entries) == (waiting, int(several.sum()))   # the entries of one item follow
    for batch, (trace_groups, resolve_groups) in enumerate(groups):
        first = batch * work.batch_items
        assert trace_groups.tolist() == [-(-min(max(items - first, 0), work.batch_items) // 64), 1, 1]
        assert resolve_groups.tolist() == [-(-min(max(waiting - first, 0), work.batch_items) // 64), 1, 1]


def test_work_list_order_balances_items():
    """The list's order: pixels of several items (whose sums wait for resolve_items) first, then those of
    one; each group by size class (a pixel's items differ by at most one sample) from the largest down,
    then by place in the film's 8 × 8 tiles. Neighbouring invocations so take nearly as many samples on
    neighbouring pixels, and the resolve pass covers only the front of the list."""
    counts = np.array([5, 0, 1, 7, 3, 3, 12, 2])
    pixels, first_items = work_list_entries(counts, 4)
    # items: 5 → 3+2 (class 3), 7 → 4+3 (4), 12 → 4+4+4 (4); single: 1, 3, 3, 2 (classes 1, 3, 3, 2)
    assert pixels.tolist() == [3, 6, 0, 4, 5, 7, 2]
    assert first_items.tolist() == [0, 2, 5, 7, 8, 9, 10]
    assert item_counts(counts, 4).tolist() == [2, 0, 1, 2, 1, 1, 3, 1]
    # 9 → 3+3+3 and 5 → 3+2 (class 3) come before 4 (class 4), a single item
    pixels, _ = work_list_entries(np.array([2, 9, 4, 5, 1]), 4)
    assert pixels.tolist() == [1, 3, 2, 0, 4]
    # a 20 × 3 film, one sample each: tile by tile (the last one cut at column 20), row by row in each
    pixels, _ = work_list_entries(np.ones(60), 4, width=20)
    rows = [[20 * y + x for x in range(*columns)] for columns in ((0, 8), (8, 16), (16, 20)) for y in range(3)]
    assert pixels.tolist() == sum(rows, [])


def test_batches_cover_every_item():
    """The batches recorded hold every item counts within the schedule's bounds can make, and no more
    than the bounds call for."""
    assert batch_count(100, 4, 64, 0, None) == 0
    assert batch_count(100, 4, 64, 31, None) == -(-100 * 8 // 64)      # every pixel 31 samples: 8 items each
    assert batch_count(100, 4, 64, 31, 300) == -(-(300 + 3 * 100) // 4 // 64)
    assert batch_count(100, 4, 64, 31, 5) == 1                          # 5 samples make at most 5 items
    rng = np.random.default_rng(4)
    for _ in range(200):
        counts = rng.integers(0, 32, 100) * (rng.uniform(size=100) < rng.uniform())
        needed = -(-int(item_counts(counts, 4).sum()) // 64)
        assert needed <= batch_count(100, 4, 64, int(counts.max()), int(counts.sum()))


def test_alias_table_matches_weights():
    weights = np.array([5.0, 1.0, 0.5, 3.0, 0.01, 7.0])
    threshold, alias = alias_table(weights)
    u = (np.arange(200000) + 0.5) / 200000
    slot = np.minimum((u * len(weights)).astype(int), len(weights) - 1)
    picked = np.where(u * len(weights) - slot < threshold[slot], slot, alias[slot])
    frequency = np.bincount(picked, minlength=len(weights)) / len(u)
    np.testing.assert_allclose(frequency, weights / weights.sum(), atol=2e-4)


def test_view_radius_is_what_the_camera_frames_at_its_target():
    camera = parse_scene(_WIDE_GROUND, "wide ground", Path.cwd()).camera
    distance = np.hypot(0.6, 3.0)   # origin (0, 1, 3), target (0, 0.4, 0)
    assert view_radius(camera) == pytest.approx(np.sqrt(2) * distance * np.tan(np.radians(camera.fov) / 2))


def test_a_wide_ground_does_not_starve_a_point_light_beside_the_objects():
    """A sun and a sky over a 16 × 16 ground, and a point light of luminance 1.3 near the objects: through
    the ground's bounding sphere (radius 11.3) the sun and the sky took 199 picks in 200; through the
    region the camera frames (radius 1.55) the point light takes 1 in 5 (BENCHMARKS.md §29)."""
    scene = parse_scene(_WIDE_GROUND, "wide ground", Path.cwd())
    geometry = GeometryBuffers.build(scene)
    materials = [scene.materials[n] for n in sorted(scene.materials)]

    def pmf_of(radius):
        table = build_emitter_table(scene, np.zeros(0, np.intp), np.zeros((0, 3, 3)), geometry.material_ids,
                                    materials, scene_radius=radius)
        pmf = table.power_pmf()
        assert table.count == 3 and pmf.sum() == pytest.approx(1.0, abs=1e-6)
        return {int(k): float(p) for k, p in zip(table.records["kind"], pmf)}

    wide = pmf_of(11.3)
    assert wide[1] > 0.15 and wide[2] > 0.15 and wide[3] > 0.15, wide
    assert pmf_of(1.0)[1] > wide[1], "a scene smaller than the view is taken at its own radius"
    assert pmf_of(1e6) == pytest.approx(wide)
    scene.camera.target = scene.camera.origin + np.float32([0, 0, -1e-30])   # a region of radius ~0
    close = pmf_of(11.3)
    assert close[2] > 0 and close[3] > 0, "the sun and the sky stay in the table, drawn rarely"


_WIDE_GROUND = {
    "camera": {"origin": [0, 1, 3], "target": [0, 0.4, 0]},
    "materials": {"ground": {"reflectance": 0.5}},
    "meshes": [{"shape": "rectangle", "material": "ground",
                "transform": {"rotate": {"axis": [1, 0, 0], "angle": -90}, "scale": 8}}],
    "lights": [{"type": "directional", "direction": [-0.85, -0.3, -0.4], "irradiance": [3.2, 2.5, 1.7]},
               {"type": "point", "position": [0.9, 1.2, 1.2], "intensity": [1.2, 1.3, 1.5]}],
    "background": [0.35, 0.5, 0.8],
}


def test_gbuffers_match_the_geometry(gpu):
    """Normals are unit, depth is the camera-axis distance of the first hit (4.9 on the
    back wall, z = -1, seen from z = 3.9 above the boxes), albedo is the material's."""
    result = render("cornell", spp=8, size=SIZE, aovs=("albedo", "normal", "depth", "spp"))
    normal, depth, albedo = result.aovs["normal"], result.aovs["depth"][..., 0], result.aovs["albedo"]
    assert np.all(np.isfinite(result.color)) and np.all(result.aovs["spp"] == 8)
    np.testing.assert_allclose(np.linalg.norm(normal, axis=-1), 1.0, atol=1e-4)
    # pixels of the back wall (z = -1, normal +z) between the ceiling and the boxes
    back_wall = (slice(6, 9), slice(10, 14))
    np.testing.assert_allclose(depth[back_wall], 4.9, rtol=1e-3)
    np.testing.assert_allclose(normal[back_wall], np.broadcast_to([0, 0, 1], normal[back_wall].shape), atol=1e-4)
    np.testing.assert_allclose(albedo[back_wall], np.broadcast_to([0.885809, 0.698859, 0.666422],
                                                                   albedo[back_wall].shape), atol=1e-5)


def _project(camera, point):
    """Film position (pixels, x right, y down) of a world point, by numpy."""
    right, up, forward = camera.basis()
    tan_x, tan_y = camera.tan_half_fov(*SIZE)
    offset = np.asarray(point, np.float64) - camera.origin
    z = np.dot(offset, forward)
    sx, sy = np.dot(offset, right) / z / tan_x, np.dot(offset, up) / z / tan_y
    return np.array([(sx + 1) / 2 * SIZE[0], (1 - sy) / 2 * SIZE[1]])


def test_motion_vectors_follow_camera_and_objects(gpu):
    """In the 'moving' scene (orbiting camera, sliding box) a pixel's motion vector is where its surface
    point was on the previous frame's film minus where it is now: checked with numpy by rebuilding the
    point from the depth plane, moving it back with its object's transforms and projecting it."""
    scene = load_scene("moving")
    frame = 6
    result = render(scene, spp=4, size=SIZE, frames=frame, aovs=("depth", "motion"))
    depth, motion = result.aovs["depth"][..., 0], result.aovs["motion"]
    now, before = scene.camera_at(frame), scene.camera_at(frame - 1)
    box = next(m for m in scene.meshes if m.name == "small-box")
    box_to_previous = box.transform_at(frame - 1).astype(np.float64) @ np.linalg.inv(box.transform_at(frame))
    box_front = box.transform_at(frame) @ np.array([0.0, 0.0, 1.0, 1.0])   # centre of the cube's +z face
    bx, by = np.floor(_project(now, box_front[:3])).astype(int)
    cases = [(3, 12, np.eye(4)), (12, 3, np.eye(4)), (12, 20, np.eye(4)), (by, bx, box_to_previous)]
    right, up, forward = now.basis()
    tan_x, tan_y = now.tan_half_fov(*SIZE)
    for y, x, to_previous in cases:
        ndc = np.array([2 * (x + 0.5) / SIZE[0] - 1, 1 - 2 * (y + 0.5) / SIZE[1]])
        direction = forward + ndc[0] * tan_x * right + ndc[1] * tan_y * up
        point = now.origin + direction / np.dot(direction, forward) * depth[y, x]
        previous_point = (to_previous @ np.append(point, 1.0))[:3]
        expected = _project(before, previous_point) - np.array([x + 0.5, y + 0.5])
        np.testing.assert_allclose(motion[y, x], expected, atol=0.05, err_msg=f"pixel ({x}, {y})")
    # the box moves against the walls behind it
    assert np.abs(motion[by, bx] - motion[12, 20]).max() > 0.1


def test_static_scene_has_zero_motion(gpu):
    assert np.all(render("cornell", spp=2, size=SIZE, aovs=("motion",)).aovs["motion"] == 0)


@pytest.mark.parametrize("max_depth", [0, -1])
def test_bad_max_depth_is_an_error(gpu, max_depth):
    from wgpu_rt.errors import WgpuRtError

    with pytest.raises(WgpuRtError, match="max_depth"):
        render("cornell", spp=1, size=SIZE, max_depth=max_depth)


def _albedo(gpu, scene, spp, aux_samples=0, delta_samples=None):
    trace = TracePass(gpu, scene, GeometryBuffers.build(scene), 32, 32, max_depth=8, seed=3)
    buffers = FrameBuffers(gpu, 32, 32)
    encoder = gpu.device.create_command_encoder()
    trace.clear(encoder, buffers)
    trace.execute(encoder, buffers, SampleSchedule(spp))
    if aux_samples:
        trace.execute_aux(encoder, buffers, aux_samples, delta_samples)
    gpu.device.queue.submit([encoder.finish()])
    return buffers.read("albedo").transpose(1, 2, 0)


def test_aux_pass_estimates_the_tracers_albedo_without_its_noise(gpu):
    """Behind cornell-glossy's glass sphere a 1-spp albedo is the reflected or the refracted surface at
    random. The aux pass estimates the same quantity (the tracer's albedo at 1024 spp) from delta-chain
    paths only: with 64 of them it is close (0.0027 on lavapipe: past the first glass bounce its paths
    take the more likely lobe, a small bias; BENCHMARKS.md §15), and 8 already beat the 1-spp plane
    several times over."""
    scene = load_scene("cornell-glossy")
    reference = _albedo(gpu, scene, 1024)
    one_spp = np.abs(_albedo(gpu, scene, 1) - reference).mean()
    aux8 = np.abs(_albedo(gpu, scene, 1, 8) - reference).mean()
    aux64 = np.abs(_albedo(gpu, scene, 1, 64) - reference).mean()
    assert aux64 < 0.004 and aux8 < one_spp / 3, (one_spp, aux8, aux64)


def test_aux_pass_spends_its_extra_samples_behind_mirrors_and_glass(gpu):
    """Pixels whose first paths meet a delta surface take delta_samples, the rest stop at the base count
    (the samples are the same numbered paths either way): a scene without mirrors or glass comes out bit
    for bit as with no extra samples; in cornell-glossy the pixels that change are those behind its
    glass sphere, each exactly as 16 samples everywhere would give it, and closer to the 1024-spp albedo."""
    plain_scene = load_scene("cornell")
    np.testing.assert_array_equal(_albedo(gpu, plain_scene, 1, 4, 16), _albedo(gpu, plain_scene, 1, 4, 4))
    scene = load_scene("cornell-glossy")
    base, adaptive, everywhere = (_albedo(gpu, scene, 1, n, m) for n, m in ((4, 4), (4, 16), (16, 16)))
    changed = np.any(adaptive != base, axis=-1)
    assert 20 <= changed.sum() <= 0.5 * changed.size, changed.sum()
    np.testing.assert_array_equal(adaptive[changed], everywhere[changed])
    reference = _albedo(gpu, scene, 1024)[changed]
    assert np.abs(adaptive[changed] - reference).mean() < 0.7 * np.abs(base[changed] - reference).mean()


WALL_ALBEDO = 0.6
PANE_TILT_DEG = 30.0
PANE_SCENE = {   # a diffuse wall seen through a tilted pane of glass; what the pane reflects is dark
    "camera": {"origin": [0, 0, 3], "target": [0, 0, 0], "fov": 30},
    "materials": {"wall": {"kind": "diffuse", "reflectance": WALL_ALBEDO},
                  "glass": {"kind": "dielectric", "ior": 1.5},
                  "light": {"kind": "diffuse", "reflectance": 0.0, "emission": [5, 5, 5]}},
    "meshes": [{"name": "wall", "shape": "rectangle", "material": "wall", "transform": {"scale": 4, "translate": [0, 0, -1]}},
               {"name": "pane", "shape": "cube", "material": "glass",
                "transform": {"rotate": {"axis": [0, 1, 0], "angle": PANE_TILT_DEG}, "scale": [0.6, 0.6, 0.02],
                              "translate": [0, 0, 0.5]}},
               {"name": "light", "shape": "rectangle", "material": "light",
                "transform": {"rotate": {"axis": [1, 0, 0], "angle": 90}, "scale": 0.5, "translate": [0, 1.5, 0]}}],
}


@pytest.mark.parametrize("delta_samples", [3, 8])
def test_aux_albedo_behind_a_pane_of_glass_is_noise_free(gpu, delta_samples):
    """Behind a flat pane every pixel's aux albedo is the wall's times the pane's transmittance 1 − F at
    the ray's incidence angle (F: Fresnel reflectance; the reflected side is black): the samples of a
    pixel behind glass (8 by default; an odd count too) share the first glass bounce's two lobes in
    proportion to F, each weighed by its lobe's share, and leave the slab along its more likely lobe. Picking the lobes at random, as the
    tracer does, spread these pixels by ±0.046 around the mean and fails this test."""
    scene = parse_scene(PANE_SCENE, "pane", Path("."))
    albedo = _albedo(gpu, scene, 1, min(4, delta_samples), delta_samples)[..., 0]
    cos_i, cos_t = _pane_cosines(scene)
    fresnel = 0.5 * (((cos_i - 1.5 * cos_t) / (cos_i + 1.5 * cos_t)) ** 2
                     + ((1.5 * cos_i - cos_t) / (1.5 * cos_i + cos_t)) ** 2)
    expected = WALL_ALBEDO * (1 - fresnel)
    np.testing.assert_allclose(albedo[BEHIND_PANE], expected[BEHIND_PANE], atol=0.004)


BEHIND_PANE = (slice(12, 20), slice(12, 20))   # well inside the pane's image, away from its rims
PANE_THICKNESS = 0.04


def _pane_cosines(scene) -> tuple[np.ndarray, np.ndarray]:
    """(32, 32) cosines of each pixel centre's ray with the pane's normal, outside and inside the glass."""
    from wgpu_rt.trace.scene_data import camera_vectors

    view = camera_vectors(scene.camera, 32, 32)
    centres = (np.arange(32) + 0.5) / 32
    film_y, film_x = np.meshgrid(centres, centres, indexing="ij")
    dirs = view["forward"] + (2 * film_x - 1)[..., None] * view["right"] + (1 - 2 * film_y)[..., None] * view["up"]
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    tilt = np.radians(PANE_TILT_DEG)
    cos_i = np.abs(dirs @ np.array([np.sin(tilt), 0.0, np.cos(tilt)]))
    return cos_i, np.sqrt(1 - (1 - cos_i ** 2) / 1.5 ** 2)


@pytest.mark.parametrize("aux_samples", [0, 4])
def test_albedo_through_tinted_absorbing_glass_carries_the_light_s_colour(gpu, aux_samples):
    """Behind the pane tinted by a transmittance T at each crossing and absorbing at a rate σ inside, the albedo the
    denoiser sees (the tracer's own at 256 spp, the aux pass's) is the clear pane's times T² exp(−σ L), L the
    length of the ray's way through the glass: the colour the wall's light takes on the way, so that the colour
    over the albedo there is the wall's own irradiance. (With the tint left out, that ratio carried the glass's
    colour, unlike anywhere the wall is seen directly.)"""
    tint, absorption = np.array([0.9, 0.6, 0.8]), np.array([0.0, 5.0, 20.0])
    clear = parse_scene(PANE_SCENE, "pane", Path("."))
    coloured = parse_scene(PANE_SCENE, "pane", Path("."))
    coloured.materials["glass"].transmittance = np.float32(tint)
    coloured.materials["glass"].absorption = np.float32(absorption)
    spp = 1 if aux_samples else 256
    ratio = _albedo(gpu, coloured, spp, aux_samples) / _albedo(gpu, clear, spp, aux_samples)
    _, cos_t = _pane_cosines(clear)
    expected = tint ** 2 * np.exp(-absorption * PANE_THICKNESS / cos_t[..., None])
    np.testing.assert_allclose(ratio[BEHIND_PANE], expected[BEHIND_PANE], rtol=0.02)   # (jitter moves L)


GLOW_REFLECTANCE = 0.3
SKY_RADIANCE = (0.3, 0.5, 2.0)
GLOW_SCENE = {   # two glowing tiles under a sky: the left one faces the camera, the right one turns its back
    "camera": {"origin": [0, 0, 3], "target": [0, 0, 0], "fov": 40},
    "materials": {"glow": {"kind": "diffuse", "reflectance": GLOW_REFLECTANCE, "emission": [0.2, 0.5, 4.0]}},
    "meshes": [{"name": "front", "shape": "rectangle", "material": "glow",
                "transform": {"scale": 0.4, "translate": [-0.5, 0, 0]}},
               {"name": "back", "shape": "rectangle", "material": "glow",
                "transform": {"rotate": {"axis": [0, 1, 0], "angle": 180}, "scale": 0.4, "translate": [0.5, 0, 0]}}],
    "background": list(SKY_RADIANCE),
}


@pytest.mark.parametrize("aux_samples", [0, 4])
@pytest.mark.parametrize("reflectance", [GLOW_REFLECTANCE, 0.0, 0.7])
def test_albedo_of_an_escape_is_the_background(gpu, aux_samples, reflectance):
    """Where a path escapes, the albedo the denoiser sees is the background's radiance, each channel at
    most 1 (wgsl/trace/guide_albedo.wgsl: what the pixel's colour is a multiple of); an emitter keeps its
    reflectance from either side, but at least 0.5 grey (a black lamp's colour read as its radiance times
    100). The tracer's own plane (aux_samples=0, one path a sample) and the aux pass's agree on it."""
    from scene_scores import first_materials

    glow = {**GLOW_SCENE["materials"]["glow"], "reflectance": reflectance}
    scene = parse_scene({**GLOW_SCENE, "materials": {"glow": glow}}, "glow", Path("."))
    albedo = _albedo(gpu, scene, 4, aux_samples)
    met = first_materials(gpu, scene, 32)
    sky = (met == "").all(axis=-1)
    tiles = (met == "glow").all(axis=-1)
    assert sky.sum() > 20 and tiles[:, :16].sum() > 20 and tiles[:, 16:].sum() > 20
    sky_albedo = np.broadcast_to(np.minimum(SKY_RADIANCE, 1.0), albedo[sky].shape)
    np.testing.assert_allclose(albedo[sky], sky_albedo, atol=1e-6)
    np.testing.assert_allclose(albedo[tiles], max(reflectance, 0.5), atol=1e-6)


def test_denoising_renders_get_the_noise_free_albedo(gpu):
    """render(denoise=True) re-estimates the albedo plane (AUX_SAMPLES paths); aux_samples=0 keeps the
    tracer's own, and a negative count is refused by name."""
    from wgpu_rt.errors import WgpuRtError

    plain = render("cornell-glossy", spp=1, size=(32, 32), seed=3, aovs=("albedo",)).aovs["albedo"]
    kept = render("cornell-glossy", spp=1, size=(32, 32), seed=3, aovs=("albedo",), aux_samples=0,
                  denoise=True).aovs["albedo"]
    clean = render("cornell-glossy", spp=1, size=(32, 32), seed=3, aovs=("albedo",), denoise=True).aovs["albedo"]
    np.testing.assert_array_equal(kept, plain)
    assert np.abs(clean - plain).max() > 0.1
    with pytest.raises(WgpuRtError, match="aux_samples"):
        render("cornell", size=(8, 8), aux_samples=-1)


@pytest.mark.parametrize("aux_samples", [0, 4])
def test_vertex_colors_tint_the_albedo_the_denoiser_sees(gpu, aux_samples):
    """A tile whose vertices carry one colour: the albedo there (the tracer's own and the aux pass's) is the
    material's reflectance times that colour as the GPU stores it (8-bit sRGB); colours that differ per
    vertex vary across it."""
    from scene_scores import first_materials

    from wgpu_rt.scene.model import vertex_colors_as_rendered

    data = {**GLOW_SCENE, "materials": {"glow": {"kind": "diffuse", "reflectance": 0.8}}, "background": [0, 0, 0]}
    scene = parse_scene(data, "tile", Path("."))
    met = first_materials(gpu, scene, 32)
    front = (met == "glow").all(axis=-1)
    front[:, 16:] = False
    for mesh in scene.meshes:
        mesh.colors = np.tile(np.float32([0.9, 0.35, 0.05]), (len(mesh.vertices), 1))
    albedo = _albedo(gpu, scene, 4, aux_samples)
    expected = 0.8 * vertex_colors_as_rendered(scene.meshes[0])[0]
    np.testing.assert_allclose(albedo[front], np.broadcast_to(expected, albedo[front].shape), rtol=1e-5)
    scene.meshes[0].colors = np.float32([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]])[:len(scene.meshes[0].vertices)]
    varied = _albedo(gpu, scene, 4, aux_samples)[front]
    assert np.ptp(varied[:, 0]) > 0.3 and np.ptp(varied[:, 1]) > 0.3
