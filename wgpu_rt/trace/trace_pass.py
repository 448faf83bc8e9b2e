"""The path-tracing pass: records dispatches of wgsl/trace/trace.wgsl that add samples to the output planes.

Every dispatch takes at most ``chunk_size`` samples per pixel, so no single dispatch runs long on a CPU
driver; the per-dispatch chunk start is copied into the frame parameters between dispatches (copies
and dispatches run in recording order), so a whole pass records into one encoder. Samples are numbered
per pixel in the order taken (the spp plane holds how many a pixel has), so any later pass, uniform or
per-pixel (adaptive), adds new sample indices and the planes stay unbiased running means.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..accel.geometry import (
    GEOMETRY_WORDS,
    NO_INSTANCES,
    UNIFORM_GEOMETRY_WORDS,
    InstancedGeometry,
    compose_with_traversal,
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
from ..scene.model import Scene
from .features import SceneFeatures
from .scene_data import (
    FRAME_PARAMS_DTYPE,
    build_emitter_table,
    camera_vectors,
    pack_materials,
)

TILE = 8   # a workgroup traces TILE × TILE pixels (wgsl/trace/trace.wgsl)
KERNEL = "trace/trace.wgsl"
AUX_KERNEL = "trace/aux.wgsl"
# Delta-chain samples per pixel of the noise-free albedo (execute_aux). 1 is worse than none (an albedo
# sample independent of the colour sample it demodulates); 4 keeps almost all of 8's gain at half the cost
# (BENCHMARKS.md §5, "Noise-free albedo").
AUX_SAMPLES = 4


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
                        instances: str = NO_INSTANCES, kernel: str = KERNEL) -> str:
    """The kernel with the traversal module ``traversal`` (default: the one that suits ``ctx``'s
    adapter, wgpu_rt.accel.geometry.traversal_module), the buffer ``placement`` and the geometry's
    ``instances`` module (its ``instances_module``)."""
    replacements = {NO_INSTANCES: instances}
    if placement.tables:
        replacements[STORAGE_TABLES] = UNIFORM_TABLES
    if placement.geometry:
        replacements[GEOMETRY_WORDS] = UNIFORM_GEOMETRY_WORDS
    return compose_with_traversal(ctx, kernel, traversal, replacements=replacements)


def trace_layout(ctx, geometry_bindings: int, placement: BufferPlacement = BufferPlacement()):
    """The kernel's pipeline layout, spelled out: "auto" would drop the bindings that a specialization
    no longer reads, and then one set of bind groups could not serve every specialization.
    Group 0 is the geometry's buffers (read-only storage; the first two uniform with
    ``placement.geometry``), group 1 the frame uniform, the material and emitter tables (uniform or
    read-only storage) and two read-only tables, group 2 the six output planes."""
    import wgpu

    key = (id(ctx.device), geometry_bindings, placement)
    if key not in _layouts:
        def group(kinds):
            return ctx.device.create_bind_group_layout(entries=[
                {"binding": i, "visibility": wgpu.ShaderStage.COMPUTE, "buffer": {"type": kind}}
                for i, kind in enumerate(kinds)])

        read_only, uniform = wgpu.BufferBindingType.read_only_storage, wgpu.BufferBindingType.uniform
        tables = uniform if placement.tables else read_only
        words = uniform if placement.geometry else read_only
        _layouts[key] = ctx.device.create_pipeline_layout(bind_group_layouts=[
            group([words] * 2 + [read_only] * (geometry_bindings - 2)),
            group([uniform, tables, tables, read_only, read_only]),
            group([wgpu.BufferBindingType.storage] * len(TracePass.outputs))])
    return _layouts[key]


_layouts: dict = {}


def trace_pipeline(ctx, features: SceneFeatures, geometry_bindings: int, traversal: str | None = None,
                   placement: BufferPlacement = BufferPlacement(), instances: str = NO_INSTANCES):
    """The kernel specialized to ``features`` (pipelines are cached by GpuContext)."""
    return ctx.compute_pipeline(trace_kernel_source(ctx, traversal, placement, instances), "main",
                                constants=features.constants(), label=f"trace {features}",
                                layout=trace_layout(ctx, geometry_bindings, placement))


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
    (a u32 plane; ``samples`` is then its maximum), with sample indices shifted by ``sample_offset``."""

    samples: int = 1
    sample_counts: object | None = None
    sample_offset: int = 0


class TracePass(ComputePass):
    """Path tracing of one frame of ``scene`` into the radiance and G-buffer planes."""

    outputs = (RADIANCE, ALBEDO, NORMAL, DEPTH, MOTION, SPP)

    def __init__(self, ctx, scene: Scene, geometry, width: int, height: int, frame: int = 0,
                 max_depth: int = 8, seed: int = 0, features: SceneFeatures | None = None,
                 chunk_size: int | None = None, traversal: str | None = None,
                 placement: BufferPlacement | None = None):
        """``traversal``: the BVH traversal module (tests and benchmarks compare them; default: the
        adapter's, wgpu_rt.accel.geometry.traversal_module). ``placement``: which tables live in
        uniform buffers (default: each that fits)."""
        if max_depth < 1:
            raise ValueError(f"max_depth must be at least 1, got {max_depth}")
        self.ctx, self.width, self.height = ctx, width, height
        self.features = features or SceneFeatures.of(scene)
        materials = [scene.materials[n] for n in scene_material_names(scene)]
        triangle_materials = [materials[i] for i in geometry.material_ids]
        emitters = build_emitter_table(scene, geometry.triangles, triangle_materials,
                                       _scene_radius(geometry.triangles))
        fitting = BufferPlacement(tables=tables_fit_uniform(len(materials), emitters.count),
                                  geometry=geometry.fits_uniform)
        self.placement = placement or fitting
        if (self.placement.tables and not fitting.tables) or (self.placement.geometry and not fitting.geometry):
            raise ValueError(f"{self.placement} asks for uniform buffers beyond their capacity ({fitting} fit)")
        geometry_buffers = geometry.upload(ctx, uniform_words=self.placement.geometry)
        self.pipeline = trace_pipeline(ctx, self.features, len(geometry_buffers), traversal, self.placement,
                                       geometry.instances_module)
        self._kernel_options = (traversal, self.placement, geometry.instances_module, len(geometry_buffers))
        self._aux_pipelines: dict[int, object] = {}
        # A two-level geometry (InstancedGeometry) follows the frame: set_frame rewrites its per-frame part.
        self._geometry, self._geometry_buffers = geometry, geometry_buffers
        instanced = isinstance(geometry, InstancedGeometry)
        if instanced and InstancedGeometry.moves_emitters(scene):
            raise ValueError(f"scene {scene.name!r}: an emissive mesh moves, which its emitter table cannot follow")
        self._placed = geometry.transform_key(geometry.frame) if instanced else None
        # Enough samples per dispatch to keep the device busy and the tail short (a subgroup runs until
        # its last invocation has traced its last path: ~11% idle turns at 16 samples, 15% at 8 on
        # cornell); few enough to stay around a second on lavapipe and well within the kernel's
        # LOOP_BUDGET (wgsl/trace/trace.wgsl) on scenes with long paths.
        self.chunk_size = chunk_size or max(1, min(16, (1 << 20) // (width * height)))

        self._emitter_table, self._max_depth = emitters, max_depth
        self.set_frame(scene, frame, seed)
        self._geometry_group = ctx.bind_group(self.pipeline, geometry_buffers, group=0)
        material_records = pack_materials(materials)
        if self.placement.tables:
            self._materials = ctx.uniform(_padded(material_records, UNIFORM_TABLE_CAPACITY["materials"]).tobytes(),
                                          label="materials")
            self._emitters = ctx.uniform(_padded(emitters.records, UNIFORM_TABLE_CAPACITY["emitters"]).tobytes(),
                                         label="emitters")
        else:
            self._materials = ctx.upload(material_records, label="materials")
            self._emitters = ctx.upload(emitters.records, label="emitters")
        self._triangle_density = ctx.upload(emitters.triangle_density, label="triangle emitter densities")
        self._no_counts = ctx.storage(16, label="no sample counts")
        self._param_buffers: dict[tuple, list] = {}
        self._chunk_starts = None
        self._bind_groups: dict[tuple, object] = {}

    def set_frame(self, scene: Scene, frame: int, seed: int) -> None:
        """Point the pass at another frame of the same geometry (camera, previous camera, seed): the
        uploaded geometry, materials and emitters are kept; a two-level geometry's instances move to
        the frame (only its small per-frame buffers are rewritten, and only when they change)."""
        self._params = self._frame_params(scene, frame, self._max_depth, seed, self._emitter_table)
        placed = self._geometry.transform_key(frame) if self._placed is not None else None
        if placed != self._placed:
            self._geometry.write_frame(self.ctx, self._geometry_buffers, frame)
            self._placed = placed

    def _frame_params(self, scene, frame, max_depth, seed, emitters) -> np.ndarray:
        w, h = self.width, self.height
        now = camera_vectors(scene.camera_at(frame), w, h)
        before = camera_vectors(scene.camera_at(frame - 1), w, h)
        tan_x, tan_y = before["tan"]
        params = np.zeros((), FRAME_PARAMS_DTYPE)
        params["camera_origin"], params["camera_right"] = now["origin"], now["right"]
        params["camera_up"], params["camera_forward"] = now["up"], now["forward"]
        params["previous_origin"], params["previous_forward"] = before["origin"], before["forward"]
        params["previous_right"] = before["unit_right"] / tan_x
        params["previous_up"] = before["unit_up"] / tan_y
        params["width"], params["height"], params["seed"], params["max_depth"] = w, h, seed, max_depth
        params["emitter_count"], params["background_pmf"] = emitters.count, emitters.background_pmf
        params["background"] = scene.background
        return params

    # A frame allocates nothing: one parameter buffer per kind of pass (its schedule's shape), rewritten
    # only when its contents change (a new camera or seed), one buffer of chunk starts (fixed contents),
    # and bind groups cached by the buffers they bind. Rewriting a buffer a submitted frame still reads
    # is safe: queue writes are ordered after earlier submissions.
    def _params_buffer(self, schedule: SampleSchedule):
        params = self._params.copy()
        params["sample_offset"] = schedule.sample_offset
        params["use_sample_counts"] = int(schedule.sample_counts is not None)
        params["pass_samples"] = schedule.samples
        params["chunk_size"] = self.chunk_size
        data = params.tobytes()
        key = (schedule.sample_offset, schedule.sample_counts is not None, schedule.samples)
        held = self._param_buffers.get(key)
        if held is None:
            held = self._param_buffers[key] = [self.ctx.uniform(data, label="frame params"), data]
        elif held[1] != data:
            self.ctx.device.queue.write_buffer(held[0], 0, data)
            held[1] = data
        return held[0]

    def _chunk_starts_buffer(self, dispatch_count: int):
        if self._chunk_starts is None or self._chunk_starts.size < 4 * dispatch_count:
            self._chunk_starts = self.ctx.upload(np.arange(max(dispatch_count, 64), dtype=np.uint32)
                                                 * self.chunk_size, label="chunk starts")
        return self._chunk_starts

    def _cached_bind_group(self, group: int, buffers: list):
        """The bind group of ``buffers``, cached by their identities (the entry holds the buffers, so an
        id cannot be reused by another buffer while it is cached; a few entries are kept)."""
        key = (group, *map(id, buffers))
        held = self._bind_groups.get(key)
        if held is None:
            if len(self._bind_groups) >= 16:
                self._bind_groups.clear()
            held = self._bind_groups[key] = (self.ctx.bind_group(self.pipeline, buffers, group=group), buffers)
        return held[0]

    def execute_aux(self, encoder, buffers: FrameBuffers, samples: int = AUX_SAMPLES) -> None:
        """Overwrite the albedo plane with a noise-free estimate of the same quantity from ``samples``
        delta-chain paths per pixel (wgsl/trace/aux.wgsl), for the denoiser: behind glass a 1-spp path
        shows the reflected or the refracted surface at random."""
        pipeline = self._aux_pipelines.get(samples)
        if pipeline is None:
            traversal, placement, instances, geometry_bindings = self._kernel_options
            pipeline = self._aux_pipelines[samples] = self.ctx.compute_pipeline(
                trace_kernel_source(self.ctx, traversal, placement, instances, AUX_KERNEL), "aux",
                constants={**self.features.constants(), "AUX_SAMPLES": samples}, label=f"aux {self.features}",
                layout=trace_layout(self.ctx, geometry_bindings, placement))
        shading = self._cached_bind_group(1, [self._params_buffer(SampleSchedule()), self._materials, self._emitters,
                                              self._triangle_density, self._no_counts])
        compute = encoder.begin_compute_pass(label="aux")
        compute.set_pipeline(pipeline)
        compute.set_bind_group(0, self._geometry_group)
        compute.set_bind_group(1, shading)
        compute.set_bind_group(2, self._cached_bind_group(2, [buffers.get(spec) for spec in self.outputs]))
        compute.dispatch_workgroups(-(-self.width // TILE), -(-self.height // TILE), 1)
        compute.end()

    def clear(self, encoder, buffers: FrameBuffers) -> None:
        """Reset the output planes (a new frame starts from zero samples)."""
        for spec in self.outputs:
            encoder.clear_buffer(buffers.get(spec))

    def execute(self, encoder, buffers: FrameBuffers, schedule: SampleSchedule = SampleSchedule()) -> None:
        """Record the dispatches that add ``schedule``'s samples to ``buffers``."""
        dispatch_count = -(-schedule.samples // self.chunk_size)
        uniform = self._params_buffer(schedule)
        chunk_starts = self._chunk_starts_buffer(dispatch_count)
        counts = schedule.sample_counts if schedule.sample_counts is not None else self._no_counts
        shading = self._cached_bind_group(1, [uniform, self._materials, self._emitters, self._triangle_density,
                                              counts])
        planes = self._cached_bind_group(2, [buffers.get(spec) for spec in self.outputs])
        groups = (-(-self.width // TILE), -(-self.height // TILE), 1)
        chunk_offset = FRAME_PARAMS_DTYPE.fields["chunk_start"][1]
        for chunk in range(dispatch_count):
            encoder.copy_buffer_to_buffer(chunk_starts, 4 * chunk, uniform, chunk_offset, 4)
            compute = encoder.begin_compute_pass(label="trace")
            compute.set_pipeline(self.pipeline)
            compute.set_bind_group(0, self._geometry_group)
            compute.set_bind_group(1, shading)
            compute.set_bind_group(2, planes)
            compute.dispatch_workgroups(*groups)
            compute.end()


def _scene_radius(triangles: np.ndarray) -> float:
    if len(triangles) == 0:
        return 1.0
    points = triangles.reshape(-1, 3)
    return float(max(1e-3, 0.5 * np.linalg.norm(points.max(0) - points.min(0))))
