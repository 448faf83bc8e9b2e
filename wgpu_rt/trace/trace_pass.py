"""The path-tracing pass: records dispatches of wgsl/trace/trace.wgsl that add samples to the output planes.

Every dispatch takes at most ``chunk_size`` samples per pixel, so no single dispatch runs long on a CPU
driver; the per-dispatch chunk start is copied into the frame parameters between dispatches (copies
and dispatches run in recording order), so a whole pass records into one encoder. Samples are numbered
per pixel in the order taken (the spp plane holds how many a pixel has), so any later pass, uniform or
per-pixel (adaptive), adds new sample indices and the planes stay unbiased running means.

A targeted pass (a sample count per pixel) does not run over the image: wgsl/trace/work_list_build.wgsl
compacts the counts into a list of work items of at most ``item_samples`` samples (``chunk_size``, at
least MIN_ITEM_SAMPLES), ordered so that
neighbours hold nearly as many samples, and wgsl/trace/targeted.wgsl traces the list in batches sized
on the device (indirect dispatches), so the pass costs what its samples cost whatever their spread.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..accel.geometry import (
    GEOMETRY_WORDS,
    NO_CUTOUTS,
    UNIFORM_GEOMETRY_WORDS,
    InstancedGeometry,
    compose_with_traversal,
    has_cutouts,
    scene_material_names,
)
from ..passes import (
    ALBEDO,
    DEPTH,
    MOTION,
    NORMAL,
    RADIANCE,
    SPP,
    ComputePass,
    FrameBuffers,
)
from ..scene.meshio import check_environment
from ..scene.model import Scene
from ..shaders import compose
from .features import SceneFeatures
from .scene_data import (
    DELTA_ROUGHNESS,
    FRAME_PARAMS_DTYPE,
    build_emitter_table,
    camera_vectors,
    emissive_triangles,
    metal_rough_coats,
    pack_environment,
    pack_materials,
    pack_textures,
)

TILE = 8   # a workgroup traces TILE × TILE pixels (wgsl/trace/trace.wgsl)
KERNEL = "trace/trace.wgsl"
AUX_KERNEL = "trace/aux.wgsl"
TARGETED_KERNEL = "trace/targeted.wgsl"
WORK_LIST_BUILD = "trace/work_list_build.wgsl"
# Work items per batch of a targeted pass at most: a batch of one item per pixel is about one uniform
# dispatch's work (an item holds up to chunk_size samples), and its slots fill 128 MiB at most, the
# smallest max-storage-buffer-binding-size WebGPU allows.
MAX_BATCH_ITEMS = 1 << 21
# A targeted pass's work items hold up to max(chunk_size, MIN_ITEM_SAMPLES) samples: an invocation that
# takes several samples of its pixel starts the next path where the last one ended, and every item pays
# a search of the list and a slot; at 1080p (chunk_size 1) items of 1 sample made the pass 1.59× a
# uniform pass of the same samples on lavapipe, items of 8 1.11× (BENCHMARKS.md §19).
MIN_ITEM_SAMPLES = 8
DISPATCH_SAMPLES = 1 << 22   # pixel samples a uniform dispatch takes at most (but at least one a pixel)
SAMPLE_SUMS_BYTES = 64   # a SampleSums (wgsl/trace/trace.wgsl) in a storage array: one item's slot
ENTRY_BYTES = 12         # an Entry (wgsl/trace/work_list.wgsl)
BATCH_ARGS_BYTES = 24    # a batch's indirect dispatch arguments: trace_items', then resolve_items' (x, y, z)
MAX_GRID = 65535         # workgroups along one dimension of a dispatch
CHUNK_START_OFFSET = FRAME_PARAMS_DTYPE.fields["chunk_start"][1]
# Delta-chain samples per pixel of the noise-free albedo (execute_aux). 1 is worse than none (an albedo
# sample independent of the colour sample it demodulates); 4 keeps almost all of 8's gain at half the cost
# at 96² (BENCHMARKS.md §5, "Noise-free albedo"). Pixels whose paths meet a mirror or smooth glass take
# AUX_DELTA_FACTOR times as many: at 256² 2× bought about two thirds of what 4× buys behind glass (up to
# 2 dB there) for a quarter to a third of its extra cost (BENCHMARKS.md §13), when each path picked its
# lobes at random; since the lobes are shared by Fresnel weight, 2× buys up to 0.16 dB over 1× for about
# twice the aux pass on glass scenes (§15): kept for quality, the first saving to take where it weighs.
AUX_SAMPLES = 4
AUX_DELTA_FACTOR = 2
# Through a thin lens every pixel's albedo mixes what each point of the aperture sees, and out of focus
# those differ (the blur itself), so AUX_SAMPLES leave it noisy: the paved plaza of
# benchmarks/scenes/plaza-lens.toml denoised 2.6 dB behind OIDN at 1 spp with 4 samples, 0.6 with 16 (§47).
AUX_LENS_FACTOR = 4
# What the albedo plane holds (wgsl/trace/guide_albedo.wgsl): where a path escapes, since version 2 the
# background's radiance, at most 1 (in 1, datasets rendered before, 0); on an emitter, since version 3 at
# least 0.5 grey (in 1 and 2 its reflectance, 0 for a black lamp); seen through mirrors and smooth glass, since
# version 4 tinted by their colour (delta_albedo_tint: before, untinted). A dataset records its version.
GUIDE_ALBEDO = 4


CUTOUTS = "trace/cutouts.wgsl"   # in place of accel/cutouts_none.wgsl where a scene cuts surfaces away
PLAIN_EMISSION = "trace/emission_plain.wgsl"              # what trace/emitters.wgsl imports
SMOOTH_COATS = "trace/coats_smooth.wgsl"                  # what trace/bsdf_plastic.wgsl imports
ROUGH_COATS = "trace/coats_rough.wgsl"                    # in its place where a scene has a rough coat
EMISSION_TEXTURES = "trace/emission_textures.wgsl"        # in its place where a scene's lights have textures
CLEAR_INTERIORS = "trace/interior_clear.wgsl"             # what trace/trace.wgsl imports
NO_PANES = "accel/panes_none.wgsl"                        # what accel/walk_tree.wgsl imports
SHADOW_PANES = "trace/shadow_panes.wgsl"                  # in its place where a scene has a thin pane
ABSORBING_INTERIORS = "trace/interior_absorbing.wgsl"     # in its place where a scene's glass absorbs
NO_METAL_ROUGH_MAPS = "trace/metal_rough_none.wgsl"       # what trace/surface.wgsl imports
METAL_ROUGH_MAPS = "trace/metal_rough_maps.wgsl"          # in its place where a mesh has a metal-rough map
STORAGE_TABLES = "trace/shading_tables_storage.wgsl"   # what trace/trace_bindings.wgsl imports
UNIFORM_TABLES = "trace/shading_tables_uniform.wgsl"
# Records per table in UNIFORM_TABLES (its array sizes): 16 KiB of materials, 40 KiB of emitters.
UNIFORM_TABLE_CAPACITY = {"materials": 256, "emitters": 512}


@dataclass(frozen=True)
class BufferPlacement:
    """Which tables the kernel reads from uniform buffers rather than storage buffers (cheaper reads at
    per-invocation indices on lavapipe, but of fixed capacity): the material and emitter tables
    (``tables``, UNIFORM_TABLE_CAPACITY) and the BVH nodes and triangle positions (``geometry``,
    wgpu_rt.accel.geometry.UNIFORM_GEOMETRY_BYTES)."""

    tables: bool = False
    geometry: bool = False


def trace_kernel_source(ctx, traversal: str | None = None, placement: BufferPlacement = BufferPlacement(),
                        geometry_modules: dict | None = None, kernel: str = KERNEL) -> str:
    """The kernel with the traversal module ``traversal`` (default: the one that suits ``ctx``'s
    adapter, wgpu_rt.accel.geometry.traversal_module), the buffer ``placement`` and the modules the
    geometry's layout needs (its ``kernel_modules``; default: a single level, threaded)."""
    replacements = dict(geometry_modules or {})
    if placement.tables:
        replacements[STORAGE_TABLES] = UNIFORM_TABLES
    if placement.geometry:
        replacements[GEOMETRY_WORDS] = UNIFORM_GEOMETRY_WORDS
    return compose_with_traversal(ctx, kernel, traversal, replacements=replacements)


def trace_layout(ctx, geometry_bindings: int, placement: BufferPlacement = BufferPlacement(),
                 work_list: bool = False):
    """The kernel's pipeline layout, spelled out: "auto" would drop the bindings that a specialization
    no longer reads, and then one set of bind groups could not serve every specialization.
    Group 0 is the geometry's buffers (read-only storage; the first two uniform with
    ``placement.geometry``), group 1 the frame uniform, the material and emitter tables (uniform or
    read-only storage) and four read-only tables (triangle emitter entries, sample counts, surface textures,
    the environment map),
    group 2 the six output planes; with ``work_list``
    (wgsl/trace/targeted.wgsl) group 3 is the work list's entries and totals (read-only) and the
    per-item sums and their entries."""
    import wgpu

    key = (id(ctx.device), geometry_bindings, placement)
    if key not in _group_layouts:
        def group(kinds):
            return ctx.device.create_bind_group_layout(entries=[
                {"binding": i, "visibility": wgpu.ShaderStage.COMPUTE, "buffer": {"type": kind}}
                for i, kind in enumerate(kinds)])

        read_only, uniform = wgpu.BufferBindingType.read_only_storage, wgpu.BufferBindingType.uniform
        storage = wgpu.BufferBindingType.storage
        tables = uniform if placement.tables else read_only
        words = uniform if placement.geometry else read_only
        # one set of group layouts for both pipeline layouts, so one set of bind groups serves both
        _group_layouts[key] = [group([words] * 2 + [read_only] * (geometry_bindings - 2)),
                               group([uniform, tables, tables, read_only, read_only, read_only, read_only]),
                               group([storage] * len(TracePass.outputs)),
                               group([read_only, read_only, storage, storage])]
    groups = _group_layouts[key]
    if (*key, work_list) not in _layouts:
        _layouts[(*key, work_list)] = ctx.device.create_pipeline_layout(
            bind_group_layouts=groups if work_list else groups[:3])
    return _layouts[(*key, work_list)]


_group_layouts: dict = {}
_layouts: dict = {}


def trace_pipeline(ctx, features: SceneFeatures, geometry_bindings: int, traversal: str | None = None,
                   placement: BufferPlacement = BufferPlacement(), geometry_modules: dict | None = None):
    """The kernel specialized to ``features`` (pipelines are cached by GpuContext)."""
    return ctx.compute_pipeline(trace_kernel_source(ctx, traversal, placement, geometry_modules), "main",
                                constants=features.constants(), label=f"trace {features}",
                                layout=trace_layout(ctx, geometry_bindings, placement))


def scatters_tile_rows(ctx) -> bool:
    """Whether tile rows are traced in a scattered order (tile_row_stride) on ``ctx``'s adapter: on CPU
    drivers, which hand each thread one contiguous range of workgroups (wgsl/trace/camera.wgsl)."""
    return ctx.adapter.info.get("adapter_type") == "CPU"


def tile_row_stride(rows: int) -> int:
    """The stride wgsl/trace/camera.wgsl's tile_pixel steps through ``rows`` tile rows by on CPU drivers:
    the integer nearest 0.618·rows that is coprime to it (so row · stride mod rows visits every row once,
    and any run of consecutive workgroup rows is spread over the whole height)."""
    target = round(0.618 * rows)
    return next(stride for distance in range(rows + 1) for stride in (target - distance, target + distance)
                if 0 < stride and math.gcd(stride, rows) == 1)


def tables_fit_uniform(material_count: int, emitter_count: int) -> bool:
    """Whether a scene's shading tables fit UNIFORM_TABLES."""
    return (material_count <= UNIFORM_TABLE_CAPACITY["materials"]
            and emitter_count <= UNIFORM_TABLE_CAPACITY["emitters"])


def _padded(records: np.ndarray, capacity: int) -> np.ndarray:
    padded = np.zeros(capacity, records.dtype)
    padded[:len(records)] = records
    return padded


@dataclass(frozen=True)
class SampleSchedule:
    """What the next ``execute`` adds: ``samples`` per pixel, or per pixel from ``sample_counts``
    (a u32 plane; ``samples`` is then its maximum, and ``total_samples``, when given, a bound on its sum
    that spares the targeted pass recording batches no count could fill), with sample indices shifted
    by ``sample_offset``."""

    samples: int = 1
    sample_counts: object | None = None
    sample_offset: int = 0
    total_samples: int | None = None


class BindGroupCache:
    """Bind groups cached by their pipeline, group and buffers' identities (an entry holds its buffers, so
    an id cannot be reused by another buffer while it is cached); a few entries are kept."""

    def __init__(self, ctx, capacity: int = 16):
        self.ctx, self.capacity = ctx, capacity
        self._held: dict[tuple, tuple] = {}

    def get(self, pipeline, group: int, buffers: list):
        key = (id(pipeline), group, *map(id, buffers))
        held = self._held.get(key)
        if held is None:
            if len(self._held) >= self.capacity:
                self._held.clear()
            held = self._held[key] = (self.ctx.bind_group(pipeline, buffers, group=group), pipeline, buffers)
        return held[0]


def item_counts(counts: np.ndarray, item_samples: int) -> np.ndarray:
    """Work items per pixel of a targeted pass: ceil(count / item_samples)."""
    return -(-np.asarray(counts, np.int64) // item_samples)


def tile_order(width: int, height: int) -> np.ndarray:
    """Each pixel's place when the film is read 8 × 8 tile by tile (tiles in raster order, the pixels of a
    tile in raster order), the order of a uniform pass's workgroups (wgsl/trace/camera.wgsl on GPUs)."""
    y, x = np.divmod(np.arange(width * height, dtype=np.int64), width)
    tile = (y // TILE) * -(-width // TILE) + x // TILE
    return tile * TILE * TILE + (y % TILE) * TILE + x % TILE


def work_list_entries(counts: np.ndarray, item_samples: int,
                      width: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """numpy reference of wgsl/trace/work_list_build.wgsl: the entries of a targeted pass's work list,
    as (pixels, first items), for ``counts`` of a film ``width`` pixels wide (default: one row). Pixels
    with samples: those of several items first, then those of one; each group by size class (the size of
    their largest item) from largest to smallest, then by place in the film's 8 × 8 tiles (tile_order).
    Each entry's items follow the previous one's."""
    counts = np.asarray(counts, np.int64).ravel()
    width = width or len(counts)
    items = item_counts(counts, item_samples)
    size_class = -(-counts // np.maximum(items, 1))
    pixels = np.flatnonzero(counts > 0)
    place = tile_order(width, len(counts) // width)[pixels]
    pixels = pixels[np.lexsort((place, -size_class[pixels], items[pixels] == 1))]
    first_items = np.concatenate([[0], np.cumsum(items[pixels])[:-1]]).astype(np.int64)
    return pixels, first_items[:len(pixels)]


def batch_count(pixels: int, item_samples: int, batch_items: int, samples: int, total_samples: int | None) -> int:
    """Batches of ``batch_items`` that hold every work item of counts of at most ``samples`` per pixel
    summing to at most ``total_samples``: a pixel's items are at most (count + item_samples − 1) /
    item_samples, and only pixels with samples have any."""
    items = pixels * -(-samples // item_samples)
    if total_samples is not None:
        items = min(items, (total_samples + (item_samples - 1) * min(pixels, total_samples)) // item_samples)
    return -(-items // batch_items)


class WorkList:
    """The device buffers and kernels that compact a targeted pass's per-pixel sample counts into work
    items (wgsl/trace/work_list_build.wgsl), and the per-item sums of one batch: all allocated once,
    sized by the frame (``batch_items`` items per batch)."""

    def __init__(self, ctx, width: int, height: int, item_samples: int, batch_items: int):
        import wgpu

        self.ctx, self.width, self.height, self.item_samples = ctx, width, height, item_samples
        if not 1 <= item_samples <= 64:
            raise ValueError(f"work items hold 1 to 64 samples, not {item_samples}")
        pixels = width * height
        self.batch_items = -(-batch_items // 64) * 64
        blocks = -(-width // TILE) * -(-height // TILE)   # one per 8 × 8 tile
        runs = -(-2 * item_samples * blocks // 64)
        self.grids = {"count_items": (min(blocks, MAX_GRID), -(-blocks // MAX_GRID)),
                      "scan_runs": (-(-runs // 64), 1), "scan_run_sums": (1, 1)}
        self.grids["place_entries"] = self.grids["count_items"]
        self.counts = ctx.storage(8 * 2 * item_samples * blocks, label="work item counts")
        self.local_offsets = ctx.storage(8 * pixels, label="work item offsets in their blocks")
        self.run_sums = ctx.storage(4 * 2 * runs, label="work item run sums")
        self.entries = ctx.storage(ENTRY_BYTES * pixels, label="work list entries")
        self.totals = ctx.storage(32, label="work list totals")   # wgsl/trace/work_list.wgsl, Totals
        self.slots = ctx.storage(SAMPLE_SUMS_BYTES * self.batch_items, label="work item sums")
        self.slot_entries = ctx.storage(4 * self.batch_items, label="work item entries")
        self._batch_args = None
        read_only, storage = wgpu.BufferBindingType.read_only_storage, wgpu.BufferBindingType.storage
        self.layout = ctx.device.create_pipeline_layout(bind_group_layouts=[ctx.device.create_bind_group_layout(
            entries=[{"binding": i, "visibility": wgpu.ShaderStage.COMPUTE, "buffer": {"type": kind}}
                     for i, kind in enumerate([read_only] * 2 + [storage] * 6)])])
        self._pipelines: dict[int, list] = {}
        self._bind_groups = BindGroupCache(ctx, capacity=8)

    def batches(self, samples: int, total_samples: int | None) -> int:
        """batch_count for this list's frame, item size and batch size."""
        return batch_count(self.width * self.height, self.item_samples, self.batch_items, samples, total_samples)

    def batch_args(self, batches: int):
        """The indirect dispatch arguments of ``batches`` batches, BATCH_ARGS_BYTES each (trace_items',
        then resolve_items'); grown as needed."""
        import wgpu

        if self._batch_args is None or self._batch_args.size < BATCH_ARGS_BYTES * batches:
            self._batch_args = self.ctx.storage(BATCH_ARGS_BYTES * max(batches, 8), label="work batch dispatch args",
                                                usage=wgpu.BufferUsage.INDIRECT)
        return self._batch_args

    def record_build(self, encoder, sample_counts, spp, batches: int) -> None:
        """Record the kernels that build the list from ``sample_counts`` (and the ``spp`` plane: the
        samples each pixel holds before the pass) and write the ``batches`` batches' dispatch args."""
        pipelines = self._pipelines.get(batches)
        if pipelines is None:
            constants = {"WIDTH": self.width, "HEIGHT": self.height, "ITEM_SAMPLES": self.item_samples,
                         "BATCH_ITEMS": self.batch_items, "BATCHES": batches}
            code = compose(WORK_LIST_BUILD)
            pipelines = self._pipelines[batches] = [
                self.ctx.compute_pipeline(code, entry, constants, label=f"work list {entry}", layout=self.layout)
                for entry in self.grids]
        bind_group = self._bind_groups.get(pipelines[0], 0, [
            sample_counts, spp, self.counts, self.local_offsets, self.run_sums, self.entries, self.totals,
            self.batch_args(batches)])
        encoder.clear_buffer(self.counts)
        compute = encoder.begin_compute_pass(label="work list")
        for pipeline, grid in zip(pipelines, self.grids.values()):
            compute.set_pipeline(pipeline)
            compute.set_bind_group(0, bind_group)
            compute.dispatch_workgroups(*grid, 1)
        compute.end()


class TracePass(ComputePass):
    """Path tracing of one frame of ``scene`` into the radiance and G-buffer planes."""

    outputs = (RADIANCE, ALBEDO, NORMAL, DEPTH, MOTION, SPP)

    def __init__(self, ctx, scene: Scene, geometry, width: int, height: int, frame: int = 0,
                 max_depth: int = 8, seed: int = 0, features: SceneFeatures | None = None,
                 chunk_size: int | None = None, traversal: str | None = None,
                 placement: BufferPlacement | None = None, batch_items: int | None = None,
                 item_samples: int | None = None):
        """``traversal``: the BVH traversal module (tests and benchmarks compare them; default: the
        adapter's, wgpu_rt.accel.geometry.traversal_module). ``placement``: which tables live in
        uniform buffers (default: each that fits). ``item_samples``: the most samples a work item of a
        targeted pass holds (default: chunk_size, at least MIN_ITEM_SAMPLES). ``batch_items``: work items
        per batch of a targeted pass (default: about one uniform dispatch's samples, at most
        MAX_BATCH_ITEMS)."""
        if max_depth < 1:
            raise ValueError(f"max_depth must be at least 1, got {max_depth}")
        self.ctx, self.width, self.height = ctx, width, height
        # tile rows traced in a scattered order on CPU drivers (wgsl/trace/camera.wgsl), else in order
        self._tile_row_stride = tile_row_stride(-(-height // TILE)) if scatters_tile_rows(ctx) else 1
        self.features = features or SceneFeatures.of(scene)
        if scene.environment is not None:
            check_environment(scene.environment, f"scene {scene.name!r}: environment map")
        materials = [scene.materials[n] for n in scene_material_names(scene)]
        emissive = emissive_triangles(geometry.material_ids, materials)
        emitters = build_emitter_table(scene, emissive, geometry.triangles[emissive], geometry.material_ids,
                                       materials, _scene_radius(geometry.triangles), geometry.object_ids, frame)
        if len(emitters.groups) > 1 and not self.features.has_emitter_groups:
            raise ValueError(f"scene {scene.name!r} has {len(emitters.groups)} emitter groups, but its kernel's "
                             f"features leave emitter groups out")
        fitting = BufferPlacement(tables=tables_fit_uniform(len(materials), emitters.count),
                                  geometry=geometry.fits_uniform)
        self.placement = placement or fitting
        if (self.placement.tables and not fitting.tables) or (self.placement.geometry and not fitting.geometry):
            raise ValueError(f"{self.placement} asks for uniform buffers beyond their capacity ({fitting} fit)")
        geometry_buffers = geometry.upload(ctx, uniform_words=self.placement.geometry)
        modules = dict(geometry.kernel_modules)
        if has_cutouts(geometry.texture_records):
            modules[NO_CUTOUTS] = CUTOUTS
        if any(mesh.emission_texture is not None and scene.materials[mesh.material].is_emissive
               for mesh in scene.meshes):
            modules[PLAIN_EMISSION] = EMISSION_TEXTURES
        if any(mesh.metal_rough_map is not None for mesh in scene.meshes):
            modules[NO_METAL_ROUGH_MAPS] = METAL_ROUGH_MAPS
        mapped_coat = bool(scene.metal_rough_iors())       # a plastic whose roughness a map sets per point
        if mapped_coat or any(m.kind == "plastic" and m.roughness >= DELTA_ROUGHNESS for m in materials):
            modules[SMOOTH_COATS] = ROUGH_COATS
        if any(m.absorbs for m in materials):
            modules[CLEAR_INTERIORS] = ABSORBING_INTERIORS
        if any(m.kind == "thin_dielectric" for m in materials):
            modules[NO_PANES] = SHADOW_PANES
        self.pipeline = trace_pipeline(ctx, self.features, len(geometry_buffers), traversal, self.placement, modules)
        self._kernel_options = (traversal, self.placement, modules, len(geometry_buffers))
        self._aux_pipelines: dict[tuple[int, int], object] = {}
        # A two-level geometry (InstancedGeometry) follows the frame: set_frame rewrites its per-frame part.
        self._geometry, self._geometry_buffers = geometry, geometry_buffers
        instanced = isinstance(geometry, InstancedGeometry)
        self._placed = geometry.transform_key(geometry.frame) if instanced else None
        # Moving emissive meshes and animated lights: the emitter table follows them (set_frame rebuilds it from
        # the frame's placed triangles and lights, with the scene radius of the frame the pass was built at).
        self._moving_emitters = instanced and InstancedGeometry.moves_emitters(scene)
        self._lights = scene.lights_key(frame) if scene.has_moving_lights else None
        self._shading = (materials, emissive, _scene_radius(geometry.triangles))
        # Enough samples per dispatch to keep the device busy and the tail short (a subgroup runs until
        # its last invocation has traced its last path: ~11% idle turns at 16 samples, 15% at 8 on
        # cornell; an invocation that takes several samples starts the next path where one ended: at
        # 1080p, 4 spp, chunks of 2 traced 8-17% faster than chunks of 1 on lavapipe, BENCHMARKS.md §19);
        # few enough to stay within a few seconds a dispatch on lavapipe for simple scenes and well within
        # the kernel's LOOP_BUDGET (wgsl/trace/trace.wgsl) on scenes with long paths.
        self.chunk_size = chunk_size or max(1, min(16, DISPATCH_SAMPLES // (width * height)))
        self.item_samples = item_samples or max(self.chunk_size, MIN_ITEM_SAMPLES)
        # a batch of the default size holds about one uniform dispatch's samples
        default_items = max(64, width * height * self.chunk_size // self.item_samples)
        self._batch_items = min(batch_items or default_items, MAX_BATCH_ITEMS)
        self._work_list: WorkList | None = None     # made by the first targeted pass
        self._targeted_pipelines: list | None = None   # trace_items and resolve_items, likewise

        self._emitter_table, self._max_depth = emitters, max_depth
        self._geometry_group = ctx.bind_group(self.pipeline, geometry_buffers, group=0)
        material_records = pack_materials(materials)
        if self.placement.tables:
            self._materials = ctx.uniform(_padded(material_records, UNIFORM_TABLE_CAPACITY["materials"]).tobytes(),
                                          label="materials")
            self._emitters = ctx.uniform(self._emitter_bytes(emitters), label="emitters")
        else:
            self._materials = ctx.upload(material_records, label="materials")
            self._emitters = ctx.upload(emitters.records, label="emitters")
        self._triangle_entry = ctx.upload(emitters.triangle_entry, label="triangle emitter entries")
        textures = pack_textures(scene.textures(), geometry.texture_records, metal_rough_coats(scene))
        ctx.check_buffer_size(textures.nbytes, f"scene {scene.name!r}: surface textures")
        self._textures = ctx.upload(textures, label="surface textures")
        environment = pack_environment(scene.environment)
        ctx.check_buffer_size(environment.nbytes, f"scene {scene.name!r}: environment map")
        self._environment = ctx.upload(environment, label="environment map")
        self.set_frame(scene, frame, seed)
        self._no_counts = ctx.storage(16, label="no sample counts")
        self._param_buffers: dict[tuple, list] = {}
        self._starts: dict[int, object] = {}
        self._bind_groups = BindGroupCache(ctx)

    def set_frame(self, scene: Scene, frame: int, seed: int) -> None:
        """Point the pass at another frame of the same geometry (camera, previous camera, seed): the
        uploaded geometry and materials are kept; a two-level geometry's instances move to the frame (only
        its small per-frame buffers are rewritten, and only when they change), and the emitter table follows
        moving emissive meshes and animated lights."""
        placed = self._geometry.transform_key(frame) if self._placed is not None else None
        lights = scene.lights_key(frame) if self._lights is not None else None
        moved = placed != self._placed
        if moved:
            self._geometry.write_frame(self.ctx, self._geometry_buffers, frame)
            self._placed = placed
        if (moved and self._moving_emitters) or lights != self._lights:
            self._move_emitters(scene, frame)
            self._lights = lights
        self._params = self._frame_params(scene, frame, self._max_depth, seed, self._emitter_table)

    def _emitter_bytes(self, emitters) -> bytes:
        records = emitters.records
        return (_padded(records, UNIFORM_TABLE_CAPACITY["emitters"]) if self.placement.tables else records).tobytes()

    def _move_emitters(self, scene: Scene, frame: int) -> None:
        """Rebuild the emitter table for the emissive meshes and lights where ``frame`` puts them and rewrite it
        in place (a transform is never singular, so no emissive triangle appears or vanishes, and an animated
        scene's lights keep their records when dark: ``DARK_LIGHT_POWER``)."""
        materials, emissive, radius = self._shading
        geometry = self._geometry
        triangles = (geometry.placed_triangles(frame, emissive) if isinstance(geometry, InstancedGeometry)
                     else geometry.triangles[emissive])
        emitters = build_emitter_table(scene, emissive, triangles, geometry.material_ids, materials, radius,
                                       geometry.object_ids, frame)
        if emitters.count != self._emitter_table.count:
            raise ValueError(f"scene {scene.name!r}, frame {frame}: {emitters.count} emitters, "
                             f"{self._emitter_table.count} at the pass's first frame")
        queue = self.ctx.device.queue
        queue.write_buffer(self._emitters, 0, self._emitter_bytes(emitters))
        if len(emissive):   # only the emissive triangles' span of the entries changes (the rest stay 0)
            first, last = int(emissive[0]), int(emissive[-1]) + 1
            queue.write_buffer(self._triangle_entry, 4 * first, emitters.triangle_entry[first:last].tobytes())
        self._emitter_table = emitters

    def _frame_params(self, scene, frame, max_depth, seed, emitters) -> np.ndarray:
        w, h = self.width, self.height
        camera = scene.camera_at(frame)
        now = camera_vectors(camera, w, h)
        before = camera_vectors(scene.camera_at(frame - 1), w, h)
        tan_x, tan_y = before["tan"]
        params = np.zeros((), FRAME_PARAMS_DTYPE)
        params["camera_origin"], params["camera_right"] = now["origin"], now["right"]
        params["camera_up"], params["camera_forward"] = now["up"], now["forward"]
        params["previous_origin"], params["previous_forward"] = before["origin"], before["forward"]
        params["previous_right"] = before["unit_right"] / tan_x
        params["previous_up"] = before["unit_up"] / tan_y
        params["width"], params["height"], params["seed"], params["max_depth"] = w, h, seed, max_depth
        params["tile_row_stride"] = self._tile_row_stride
        params["emitter_count"] = emitters.count
        params["background_share"], params["background_group"] = emitters.background_share, emitters.background_group
        params["emitter_group_count"] = len(emitters.groups)
        params["emitter_groups"][:len(emitters.groups)] = emitters.groups
        params["background"] = scene.background
        params["lens_radius"], params["focus_distance"] = camera.aperture_radius, camera.focus_distance
        turn = np.radians(scene.environment_rotation)
        params["environment_turn"] = np.cos(turn), np.sin(turn)
        return params

    # A frame allocates nothing: one parameter buffer per kind of pass (its schedule's shape), rewritten
    # only when its contents change (a new camera or seed), one buffer of chunk starts (fixed contents),
    # and bind groups cached by the buffers they bind. Rewriting a buffer a submitted frame still reads
    # is safe: queue writes are ordered after earlier submissions.
    def _params_buffer(self, schedule: SampleSchedule):
        params = self._params.copy()
        params["sample_offset"] = schedule.sample_offset
        params["pass_samples"] = schedule.samples
        params["chunk_size"] = self.item_samples if schedule.sample_counts is not None else self.chunk_size
        data = params.tobytes()
        key = (schedule.sample_offset, schedule.sample_counts is not None, schedule.samples)
        held = self._param_buffers.get(key)
        if held is None:
            held = self._param_buffers[key] = [self.ctx.uniform(data, label="frame params"), data]
        elif held[1] != data:
            self.ctx.device.queue.write_buffer(held[0], 0, data)
            held[1] = data
        return held[0]

    def _starts_buffer(self, count: int, step: int):
        """0, step, 2·step, … (``count`` of them at least): what the dispatches copy into chunk_start."""
        held = self._starts.get(step)
        if held is None or held.size < 4 * count:
            held = self._starts[step] = self.ctx.upload(np.arange(max(count, 64), dtype=np.uint32) * step,
                                                        label="chunk starts")
        return held

    def _bind_group(self, group: int, buffers: list, pipeline=None):
        """The bind group of ``buffers`` for ``group`` of ``pipeline``'s layout (default: the tracer's)."""
        return self._bind_groups.get(pipeline or self.pipeline, group, buffers)

    def execute_aux(self, encoder, buffers: FrameBuffers, samples: int = AUX_SAMPLES,
                    delta_samples: int | None = None) -> None:
        """Overwrite the albedo plane with a noise-free estimate of the same quantity from ``samples``
        delta-chain paths per pixel (wgsl/trace/aux.wgsl), for the denoiser: behind glass a 1-spp path
        shows the reflected or the refracted surface at random. Pixels whose first paths meet a mirror
        or smooth glass take ``delta_samples`` (default ``AUX_DELTA_FACTOR × samples``; never fewer
        than ``samples``), which share the first glass bounce's two lobes by Fresnel weight instead of
        picking one at random. Through a thin lens both counts are AUX_LENS_FACTOR times as many, and the
        normal and depth planes are overwritten with the samples' means as well."""
        delta_samples = max(samples, AUX_DELTA_FACTOR * samples if delta_samples is None else delta_samples)
        if self._params["lens_radius"] > 0:
            samples, delta_samples = AUX_LENS_FACTOR * samples, AUX_LENS_FACTOR * delta_samples
        pipeline = self._aux_pipelines.get((samples, delta_samples))
        if pipeline is None:
            traversal, placement, geometry_modules, geometry_bindings = self._kernel_options
            pipeline = self._aux_pipelines[samples, delta_samples] = self.ctx.compute_pipeline(
                trace_kernel_source(self.ctx, traversal, placement, geometry_modules, AUX_KERNEL), "aux",
                constants={**self.features.constants(), "AUX_SAMPLES": samples, "AUX_DELTA_SAMPLES": delta_samples},
                label=f"aux {self.features}", layout=trace_layout(self.ctx, geometry_bindings, placement))
        shading = self._bind_group(1, [self._params_buffer(SampleSchedule()), self._materials, self._emitters,
                                       self._triangle_entry, self._no_counts, self._textures, self._environment])
        compute = encoder.begin_compute_pass(label="aux")
        compute.set_pipeline(pipeline)
        compute.set_bind_group(0, self._geometry_group)
        compute.set_bind_group(1, shading)
        compute.set_bind_group(2, self._bind_group(2, [buffers.get(spec) for spec in self.outputs]))
        compute.dispatch_workgroups(-(-self.width // TILE), -(-self.height // TILE), 1)
        compute.end()

    def clear(self, encoder, buffers: FrameBuffers) -> None:
        """Reset the output planes (a new frame starts from zero samples)."""
        for spec in self.outputs:
            encoder.clear_buffer(buffers.get(spec))

    def execute(self, encoder, buffers: FrameBuffers, schedule: SampleSchedule = SampleSchedule()) -> None:
        """Record the dispatches that add ``schedule``'s samples to ``buffers``."""
        uniform = self._params_buffer(schedule)
        counts = schedule.sample_counts if schedule.sample_counts is not None else self._no_counts
        shading = self._bind_group(1, [uniform, self._materials, self._emitters, self._triangle_entry, counts,
                                       self._textures, self._environment])
        planes = self._bind_group(2, [buffers.get(spec) for spec in self.outputs])
        if schedule.sample_counts is not None:
            self._execute_targeted(encoder, buffers, schedule, uniform, shading, planes)
            return
        dispatch_count = -(-schedule.samples // self.chunk_size)
        chunk_starts = self._starts_buffer(dispatch_count, self.chunk_size)
        groups = (-(-self.width // TILE), -(-self.height // TILE), 1)
        for chunk in range(dispatch_count):
            encoder.copy_buffer_to_buffer(chunk_starts, 4 * chunk, uniform, CHUNK_START_OFFSET, 4)
            compute = encoder.begin_compute_pass(label="trace")
            compute.set_pipeline(self.pipeline)
            compute.set_bind_group(0, self._geometry_group)
            compute.set_bind_group(1, shading)
            compute.set_bind_group(2, planes)
            compute.dispatch_workgroups(*groups)
            compute.end()

    @property
    def batch_items(self) -> int:
        """Work items per batch of a targeted pass."""
        return self._batch_items

    @property
    def work_list(self) -> WorkList | None:
        """The targeted passes' work list (None before the first targeted pass)."""
        return self._work_list

    def _execute_targeted(self, encoder, buffers: FrameBuffers, schedule: SampleSchedule, uniform, shading,
                          planes) -> None:
        """The samples of ``schedule.sample_counts``, traced over the compacted work list, a batch at a time."""
        if self._work_list is None:
            self._work_list = WorkList(self.ctx, self.width, self.height, self.item_samples, self._batch_items)
            traversal, placement, geometry_modules, geometry_bindings = self._kernel_options
            code = trace_kernel_source(self.ctx, traversal, placement, geometry_modules, TARGETED_KERNEL)
            layout = trace_layout(self.ctx, geometry_bindings, placement, work_list=True)
            self._targeted_pipelines = [self.ctx.compute_pipeline(code, entry, constants=self.features.constants(),
                                                                  label=f"{entry} {self.features}", layout=layout)
                                        for entry in ("trace_items", "resolve_items")]
        work = self._work_list
        batches = work.batches(schedule.samples, schedule.total_samples)
        if batches == 0:
            return
        work.record_build(encoder, schedule.sample_counts, buffers.get(SPP), batches)
        trace_items, resolve_items = self._targeted_pipelines
        items = self._bind_group(3, [work.entries, work.totals, work.slots, work.slot_entries], trace_items)
        batch_starts = self._starts_buffer(batches, work.batch_items)
        arguments = work.batch_args(batches)
        for batch in range(batches):
            encoder.copy_buffer_to_buffer(batch_starts, 4 * batch, uniform, CHUNK_START_OFFSET, 4)
            compute = encoder.begin_compute_pass(label="targeted trace")
            compute.set_pipeline(trace_items)
            compute.set_bind_group(0, self._geometry_group)
            compute.set_bind_group(1, shading)
            compute.set_bind_group(2, planes)
            compute.set_bind_group(3, items)
            compute.dispatch_workgroups_indirect(arguments, BATCH_ARGS_BYTES * batch)
            compute.set_pipeline(resolve_items)
            compute.dispatch_workgroups_indirect(arguments, BATCH_ARGS_BYTES * batch + 12)
            compute.end()


def _scene_radius(triangles: np.ndarray) -> float:
    if len(triangles) == 0:
        return 1.0
    points = triangles.reshape(-1, 3)
    return float(max(1e-3, 0.5 * np.linalg.norm(points.max(0) - points.min(0))))
