"""RayQuery: batches of rays against GeometryBuffers on the GPU (wgsl/accel/ray_query.wgsl).

Tests use it to check BVH traversal against brute force, benchmarks to time traversal. Bindings:
group 0 is the geometry (GeometryBuffers.upload); group 1 is ``rays`` (48-byte QueryRay), ``hits``
(Hit: t, u, v, prim), ``surfaces`` (HitSurface, 48 bytes) and ``occlusion`` (u32 per ray).
"""

from __future__ import annotations

import numpy as np

from .geometry import compose_with_traversal

WORKGROUP_SIZE = 64
QUERY_RAY_DTYPE = np.dtype([("origin", "<f4", 3), ("t_max", "<f4"), ("dir", "<f4", 3), ("offset", "<u4"),
                            ("normal", "<f4", 3), ("_pad", "<u4")])
HIT_DTYPE = np.dtype([("t", "<f4"), ("u", "<f4"), ("v", "<f4"), ("prim", "<u4")])
SURFACE_DTYPE = np.dtype([("shading_normal", "<f4", 3), ("material", "<u4"), ("geometric_normal", "<f4", 3),
                          ("object", "<u4"), ("previous_position", "<f4", 3), ("_pad", "<u4")])
NO_HIT = 0xFFFFFFFF


def query_rays(origins, dirs, t_max=np.inf, offset_normals=None) -> np.ndarray:
    """Rays as QUERY_RAY_DTYPE; rays with a non-zero offset normal start at offset_ray_origin."""
    origins = np.asarray(origins, np.float32).reshape(-1, 3)
    rays = np.zeros(len(origins), QUERY_RAY_DTYPE)
    rays["origin"], rays["dir"] = origins, np.asarray(dirs, np.float32).reshape(-1, 3)
    rays["t_max"] = np.broadcast_to(np.asarray(t_max, np.float32), len(origins))
    if offset_normals is not None:
        normals = np.asarray(offset_normals, np.float32).reshape(-1, 3)
        rays["normal"], rays["offset"] = normals, np.any(normals != 0, axis=1)
    return rays


class RayQuery:
    """The two entry points of accel/ray_query.wgsl, bound to one scene's uploaded geometry."""

    def __init__(self, ctx, geometry, traversal: str | None = None):
        """``traversal``: the traversal module (default: geometry.traversal_module(ctx))."""
        self.ctx = ctx
        self.geometry_buffers = geometry.upload(ctx)
        code = compose_with_traversal(ctx, "accel/ray_query.wgsl", traversal,
                                      replacements=geometry.kernel_modules)
        self.pipelines = {entry: ctx.compute_pipeline(code, entry, label=f"ray_query.{entry}")
                          for entry in ("intersect", "occluded")}

    def record(self, encoder, entry: str, rays_buffer, outputs: list, ray_count: int) -> None:
        """Record one dispatch of ``entry`` over ``ray_count`` rays into ``encoder``; ``outputs`` are
        group 1 bindings 1..3 (None where the entry point does not use one)."""
        pipeline = self.pipelines[entry]
        # `occluded` reads no triangle attributes or motion (the auto layout drops those bindings).
        geometry = (self.geometry_buffers if entry == "intersect"
                    else [None if i in (2, 3) else b for i, b in enumerate(self.geometry_buffers)])
        compute = encoder.begin_compute_pass()
        compute.set_pipeline(pipeline)
        compute.set_bind_group(0, self.ctx.bind_group(pipeline, geometry, group=0))
        compute.set_bind_group(1, self.ctx.bind_group(pipeline, [rays_buffer, *outputs], group=1))
        compute.dispatch_workgroups((ray_count + WORKGROUP_SIZE - 1) // WORKGROUP_SIZE)
        compute.end()

    def _run(self, entry: str, rays: np.ndarray, output_dtypes: list):
        rays_buffer = self.ctx.upload(rays, label="query rays")
        outputs = [None if dtype is None else self.ctx.storage(len(rays) * dtype.itemsize, label=f"{entry} out")
                   for dtype in output_dtypes]
        encoder = self.ctx.device.create_command_encoder()
        self.record(encoder, entry, rays_buffer, outputs, len(rays))
        self.ctx.device.queue.submit([encoder.finish()])
        return [None if buffer is None else self.ctx.read(buffer, np.uint8, nbytes=len(rays) * dtype.itemsize).view(dtype)
                for buffer, dtype in zip(outputs, output_dtypes)]

    def intersect(self, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(hits as HIT_DTYPE, surfaces as SURFACE_DTYPE) for QUERY_RAY_DTYPE ``rays``."""
        hits, surfaces, _ = self._run("intersect", rays, [HIT_DTYPE, SURFACE_DTYPE, None])
        return hits, surfaces

    def occluded(self, rays: np.ndarray) -> np.ndarray:
        """Boolean per ray: is anything hit in (0, t_max)?"""
        (_, _, occlusion) = self._run("occluded", rays, [None, None, np.dtype("<u4")])
        return occlusion.astype(bool)
