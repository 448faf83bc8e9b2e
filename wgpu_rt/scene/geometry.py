"""GeometryBuffers: a Scene at one frame as world-space triangles in BVH order (bind group 0).

See ARCHITECTURE.md, "Geometry". The GPU layout, in binding order, matches wgsl/geometry_bindings.wgsl:

0. ``bvh_nodes``: the BVH's 32-byte threaded nodes (``wgpu_rt.bvh.threaded_nodes``).
1. ``tri_positions``: three vec4f per triangle (xyz = world vertex, w = 0).
2. ``tri_attributes``: per triangle ``{n0, material, n1, object, n2, pad}`` (48 bytes): the three
   world-space shading normals (the mesh's vertex normals, else its face normal) and the ids.
3. ``object_motion``: one column-major mat4x4f per object (mesh index): world at this frame → world
   at the previous frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import shaders
from ..bvh import Bvh, build_bvh, threaded_nodes
from ..errors import SceneError
from .model import Scene
from .transforms import transform_normals, transform_points


def scene_material_names(scene: Scene) -> list[str]:
    """Material names in material-id order (the order of ``scene.materials``)."""
    return list(scene.materials)


def _face_normals(triangles: np.ndarray) -> np.ndarray:
    """Unit normals of (T, 3, 3) triangles by winding; +z for zero-area ones (which never get hit)."""
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]).astype(np.float64)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.where(length > 0, normals / np.where(length > 0, length, 1.0), [0.0, 0.0, 1.0]).astype(np.float32)


@dataclass
class GeometryBuffers:
    triangles: np.ndarray          # (T, 3, 3) f32 world-space vertices, BVH order
    shading_normals: np.ndarray    # (T, 3, 3) f32 unit world-space normals per vertex
    material_ids: np.ndarray       # (T,) u32 index into scene_material_names(scene)
    object_ids: np.ndarray         # (T,) u32 index into scene.meshes
    object_motion: np.ndarray      # (O, 4, 4) f32 world at this frame → world at the previous frame
    bvh: Bvh

    @classmethod
    def build(cls, scene: Scene, frame: int = 0) -> "GeometryBuffers":
        material_index = {name: i for i, name in enumerate(scene_material_names(scene))}
        triangles, normals, materials, objects, motion = [], [], [], [], []
        for object_id, mesh in enumerate(scene.meshes):
            if mesh.material not in material_index:
                raise SceneError(f"scene {scene.name!r}: mesh {mesh.name!r}: unknown material {mesh.material!r}")
            faces = np.asarray(mesh.faces, np.int64)
            transform = mesh.transform_at(frame).astype(np.float64)
            world = transform_points(transform, mesh.vertices)[faces]
            if mesh.normals is None:
                shading = np.repeat(_face_normals(world)[:, None], 3, axis=1)
            else:
                shading = transform_normals(transform, mesh.normals)[faces]
            triangles.append(world)
            normals.append(shading)
            materials.append(np.full(len(faces), material_index[mesh.material], np.uint32))
            objects.append(np.full(len(faces), object_id, np.uint32))
            motion.append(mesh.transform_at(frame - 1).astype(np.float64) @ np.linalg.inv(transform))
        if not triangles or sum(len(t) for t in triangles) == 0:
            raise SceneError(f"scene {scene.name!r}: no triangles to render")
        all_triangles = np.concatenate(triangles)
        if not np.all(np.isfinite(all_triangles)):
            raise SceneError(f"scene {scene.name!r}: a transform produced NaN or infinite vertices")
        bvh = build_bvh(all_triangles)
        order = bvh.order
        return cls(all_triangles[order], np.concatenate(normals)[order], np.concatenate(materials)[order],
                   np.concatenate(objects)[order], np.asarray(motion, np.float32), bvh)

    @property
    def triangle_count(self) -> int:
        return len(self.triangles)

    def packed_arrays(self) -> list[np.ndarray]:
        """The four arrays of bind group 0, laid out byte for byte as wgsl/bvh.wgsl reads them."""
        count = self.triangle_count
        positions = np.zeros((count, 3, 4), np.float32)
        positions[..., :3] = self.triangles
        attributes = np.zeros((count, 12), np.float32)
        attributes[:, [0, 1, 2, 4, 5, 6, 8, 9, 10]] = self.shading_normals.reshape(count, 9)
        attributes_u32 = attributes.view(np.uint32)
        attributes_u32[:, 3], attributes_u32[:, 7] = self.material_ids, self.object_ids
        column_major = np.ascontiguousarray(np.transpose(self.object_motion, (0, 2, 1)))
        return [threaded_nodes(self.bvh), positions, attributes, column_major]

    def upload(self, ctx) -> list:
        """GPU storage buffers in binding order 0..3 of group 0 (DeviceLimitError if one is too big)."""
        labels = ("BVH nodes", "triangle positions", "triangle attributes", "object motion")
        arrays = self.packed_arrays()
        for array, label in zip(arrays, labels):
            ctx.check_buffer_size(array.nbytes, f"{label} ({self.triangle_count} triangles)")
        return [ctx.upload(array, label=label) for array, label in zip(arrays, labels)]


# The kernels import traversal_lanes.wgsl; traversal_module() may swap in this one.
LANES_TRAVERSAL = "traversal_lanes.wgsl"
SUBGROUP_TRAVERSAL = "traversal_subgroup.wgsl"
MIN_PACKET_LANES = 8     # traversal_subgroup.wgsl fetches 8-word records, one word per lane

def traversal_module(ctx) -> str:
    """The traversal module for ``ctx``'s adapter: subgroup packets on a CPU adapter whose subgroups
    have at least MIN_PACKET_LANES lanes numbered along local_invocation_index of a 1-D workgroup of 64
    (GpuContext.subgroup_sizes), where shared fetches pay off (see wgsl/traversal_subgroup.wgsl); else
    per-lane traversal. Kernels that traverse use 1-D workgroups of 64 invocations."""
    sizes = ctx.subgroup_sizes
    if (sizes is not None and ctx.adapter.info.get("adapter_type") == "CPU"
            and np.all(sizes == sizes[0]) and sizes[0] >= MIN_PACKET_LANES):
        return SUBGROUP_TRAVERSAL
    return LANES_TRAVERSAL


def compose_with_traversal(ctx, kernel: str, module: str | None = None) -> str:
    """WGSL of ``kernel`` (which imports bvh.wgsl) with ``module`` (default: traversal_module(ctx))."""
    return shaders.compose(kernel, replacements={LANES_TRAVERSAL: module or traversal_module(ctx)})
