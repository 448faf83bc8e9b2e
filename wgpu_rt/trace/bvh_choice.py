"""The BVH variant a single-level scene is traced with, chosen per adapter by measurement.

``WGPU_RT_BVH`` (wgpu_rt.accel.geometry.bvh_layout) names a variant, or is ``auto`` (the default): a
scene of at least AUTO_MIN_TRIANGLES triangles is traced one sample per pixel with each variant
``bvh_variants`` offers for the adapter's traversal module (the threaded binary walk and the 4-wide
stack walk, the latter also over a tree built with small leaves; beside the per-invocation traversal also
the quantized wide layout, and each with its nodes and vertices fetched as 16-byte rows; the images are
the same), by the kernel the renderer will run, and the fastest is taken. The
choice is remembered per adapter, driver, traversal module (lanes alone or subgroup packets) and scene
size (triangles to the nearest power of two) in the measured-choices cache (wgpu_rt.measured_choices),
so each adapter measures a size once.

The probe frame starts at PROBE_MIN_SIDE² pixels and doubles its side (up to PROBE_MAX_SIDE) until one
trace takes PROBE_SECONDS, so that a GPU is timed with enough rays to fill it rather than by its
latency; each variant is then traced PROBE_RUNS times after its first trace (which compiles its kernel;
the winner's stays compiled for the render) and its median counts. On lavapipe the measurement adds about a
second to the first render of a scene size (BENCHMARKS.md §19). Smaller scenes are not measured (the
walks differ there by milliseconds a frame on lavapipe, less than the probe costs): they take
``unmeasured_layout``, the threaded walk on CPU adapters and the 4-wide one fetched as rows on GPUs,
where it traced `cornell` 1.6× as fast as the threaded walk on an H200 (BENCHMARKS.md §21). So do
two-level scenes' bottom levels (the 4-wide walk beat the threaded one on every scene the H200 traced,
the 70k-triangle bunny by 1.34×; a moving bunny walked threaded cost 1.18× the static one a frame, §22).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from ..accel.geometry import GeometryBuffers, bvh_variants, split_variant, traversal_module
from ..measured_choices import MeasuredChoices
from ..passes import RADIANCE, FrameBuffers
from ..scene.model import Scene
from .trace_pass import SampleSchedule, TracePass

AUTO_MIN_TRIANGLES = 4096
DEFAULT_LAYOUT = "threaded"
PROBE_MIN_SIDE, PROBE_MAX_SIDE = 128, 1024
PROBE_SECONDS = 0.02
PROBE_RUNS = 3


def unmeasured_layout(ctx, traversal: str) -> str:
    """The variant taken without measuring: that of a scene under AUTO_MIN_TRIANGLES triangles, and of a
    two-level scene's bottom levels (moving meshes, instancing): the threaded walk on CPU adapters (its
    stackless loop suits lavapipe's subgroup packets), else the 4-wide walk (fetched as rows where
    ``traversal`` takes them). H200, 1024² at 64 spp: `cornell` 648 against 401 M samples/s threaded,
    `cornell-glossy` 179 against 140."""
    if ctx.adapter.info.get("adapter_type") == "CPU":
        return DEFAULT_LAYOUT
    variants = bvh_variants(traversal)
    return "wide+rows" if "wide+rows" in variants else "wide"


def remembers_small_leaves(ctx, scene: Scene, choices: MeasuredChoices | None = None) -> bool:
    """Whether the variant this adapter measured fastest for ``scene``'s size (``choose_layout``) is built
    with small leaves; False where it has not measured that size yet. The renderer builds that tree
    first, so a remembered choice costs one BVH build, not two."""
    triangles = sum(len(mesh.faces) for mesh in scene.meshes)
    if triangles < AUTO_MIN_TRIANGLES:
        return False
    choices = choices or MeasuredChoices(ctx)
    traversal = traversal_module(ctx)
    variant = choices.cached(layout_key(choices, traversal, triangles), bvh_variants(traversal))
    return variant is not None and split_variant(variant)[1]


def wall_timer(run: Callable[[], float]) -> float:
    """Median seconds of PROBE_RUNS calls of ``run`` (a probe has run once already: compiled, warm)."""
    return float(np.median([run() for _ in range(PROBE_RUNS)]))


def layout_key(choices: MeasuredChoices, traversal: str, triangles: int) -> str:
    """The cache key of a layout choice for a scene of ``triangles`` triangles."""
    return f"{choices.adapter} | BVH layout | {traversal} | ~2^{round(math.log2(max(triangles, 1)))} triangles"


def choose_layout(ctx, scene: Scene, geometry: GeometryBuffers, max_depth: int = 8, frame: int = 0,
                  choices: MeasuredChoices | None = None) -> GeometryBuffers:
    """``geometry`` (``scene`` at ``frame``) as the variant that traces it fastest on this adapter (see the
    module's docstring). ``choices``: the cache (default: the shared one, timed by the wall clock; tests pass a
    fake timer, which gets (variant, run) pairs)."""
    traversal = traversal_module(ctx)
    if geometry.triangle_count < AUTO_MIN_TRIANGLES:
        return geometry.as_variant(unmeasured_layout(ctx, traversal))
    choices = choices or MeasuredChoices(ctx, timer=lambda candidate: wall_timer(candidate[1]))
    side = []   # the probe's side, found on the first measurement

    def probe(variant: str) -> tuple[str, Callable[[], float]]:
        laid_out = geometry.as_variant(variant)

        def run_at(size: int) -> Callable[[], float]:
            trace = TracePass(ctx, scene, laid_out, size, size, frame=frame, max_depth=max_depth)
            buffers = FrameBuffers(ctx, size, size)

            def run() -> float:
                started = time.perf_counter()
                encoder = ctx.device.create_command_encoder(label="wgpu-rt BVH layout probe")
                trace.execute(encoder, buffers, SampleSchedule())
                ctx.device.queue.submit([encoder.finish()])
                ctx.read(buffers.get(RADIANCE), nbytes=16)   # waits for the trace
                return time.perf_counter() - started
            return run

        size = side[0] if side else PROBE_MIN_SIDE
        while True:
            run = run_at(size)
            run()   # the first call compiles the kernel
            if side or size >= PROBE_MAX_SIDE or run() >= PROBE_SECONDS:
                break
            size *= 2
        side[:] = [size]
        return variant, run

    key = layout_key(choices, traversal, geometry.triangle_count)
    variants = bvh_variants(traversal)
    chosen = choices.choose(key, {name: (lambda name=name: probe(name)) for name in variants}, DEFAULT_LAYOUT)
    return geometry.as_variant(chosen)
