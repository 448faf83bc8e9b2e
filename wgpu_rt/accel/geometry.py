"""GeometryBuffers: a Scene at one frame as world-space triangles in BVH order (bind group 0).

See ARCHITECTURE.md, "Geometry". The GPU layout, in binding order, matches wgsl/accel/geometry_bindings.wgsl:

0. ``bvh_nodes``: the BVH's 32-byte threaded nodes, one depth-first copy per direction octant
   (``wgpu_rt.accel.bvh.ordered_threaded_nodes``).
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
from .bvh import ORDERINGS, THREADED_NODE_DTYPE, Bvh, build_bvh, ordered_threaded_nodes
from ..errors import SceneError
from ..scene.model import Scene
from ..scene.transforms import transform_normals, transform_points


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

    def orderings(self, ctx) -> int:
        """Direction-ordered node copies to upload: ORDERINGS, or 1 (the walk then takes copy 0 for every
        direction: correct, just less culling) when ORDERINGS copies exceed one storage binding."""
        node_bytes = self.bvh.node_count * THREADED_NODE_DTYPE.itemsize
        limit = min(ctx.limits["max-storage-buffer-binding-size"], ctx.limits["max-buffer-size"])
        return ORDERINGS if ORDERINGS * node_bytes <= limit else 1

    def packed_arrays(self, orderings: int = ORDERINGS) -> list[np.ndarray]:
        """The four arrays of bind group 0, laid out byte for byte as wgsl/accel/bvh.wgsl reads them."""
        count = self.triangle_count
        positions = np.zeros((count, 3, 4), np.float32)
        positions[..., :3] = self.triangles
        attributes = np.zeros((count, 12), np.float32)
        attributes[:, [0, 1, 2, 4, 5, 6, 8, 9, 10]] = self.shading_normals.reshape(count, 9)
        attributes_u32 = attributes.view(np.uint32)
        attributes_u32[:, 3], attributes_u32[:, 7] = self.material_ids, self.object_ids
        column_major = np.ascontiguousarray(np.transpose(self.object_motion, (0, 2, 1)))
        return [ordered_threaded_nodes(self.bvh, orderings), positions, attributes, column_major]

    @property
    def fits_uniform(self) -> bool:
        """Whether the nodes and positions fit UNIFORM_GEOMETRY_WORDS' buffers."""
        node_bytes = ORDERINGS * self.bvh.node_count * THREADED_NODE_DTYPE.itemsize
        return max(node_bytes, self.triangle_count * POSITION_BYTES) <= UNIFORM_GEOMETRY_BYTES

    def upload(self, ctx, uniform_words: bool = False) -> list:
        """GPU buffers in binding order 0..3 of group 0 (DeviceLimitError if one is too big): all storage,
        or (``uniform_words``, for kernels composed with UNIFORM_GEOMETRY_WORDS) the nodes and positions
        in zero-padded uniform buffers."""
        labels = ("BVH nodes", "triangle positions", "triangle attributes", "object motion")
        arrays = self.packed_arrays(self.orderings(ctx))
        for array, label in zip(arrays, labels):
            ctx.check_buffer_size(array.nbytes, f"{label} ({self.triangle_count} triangles)")
        buffers = [ctx.upload(array, label=label) for array, label in zip(arrays[2:], labels[2:])]
        if not uniform_words:
            return [ctx.upload(array, label=label) for array, label in zip(arrays[:2], labels[:2])] + buffers
        if not self.fits_uniform:
            raise ValueError(f"{self.triangle_count} triangles exceed the uniform geometry buffers")
        words = [array.tobytes().ljust(UNIFORM_GEOMETRY_BYTES, b"\0") for array in arrays[:2]]
        return [ctx.uniform(data, label=label) for data, label in zip(words, labels[:2])] + buffers


# accel/geometry_bindings.wgsl imports GEOMETRY_WORDS (storage); kernels whose geometry fits may swap in
# UNIFORM_GEOMETRY_WORDS (uniform buffers of UNIFORM_GEOMETRY_BYTES each, its array sizes).
GEOMETRY_WORDS = "accel/geometry_words.wgsl"
UNIFORM_GEOMETRY_WORDS = "accel/geometry_words_uniform.wgsl"
UNIFORM_GEOMETRY_BYTES = 65536
POSITION_BYTES = 48      # three vec4f per triangle

# The kernels import accel/traversal_lanes.wgsl; traversal_module() may swap in this one.
LANES_TRAVERSAL = "accel/traversal_lanes.wgsl"
SUBGROUP_TRAVERSAL = "accel/traversal_subgroup.wgsl"
MIN_PACKET_LANES = 8     # accel/traversal_subgroup.wgsl fetches 8-word records, one word per lane

def traversal_module(ctx) -> str:
    """The traversal module for ``ctx``'s adapter: subgroup packets on a CPU adapter whose subgroups
    have at least MIN_PACKET_LANES lanes numbered along local_invocation_index of a 1-D workgroup of 64
    (GpuContext.subgroup_sizes), where shared fetches pay off (see wgsl/accel/traversal_subgroup.wgsl); else
    per-lane traversal. Kernels that traverse use 1-D workgroups of 64 invocations."""
    sizes = ctx.subgroup_sizes
    if (sizes is not None and ctx.adapter.info.get("adapter_type") == "CPU"
            and np.all(sizes == sizes[0]) and sizes[0] >= MIN_PACKET_LANES):
        return SUBGROUP_TRAVERSAL
    return LANES_TRAVERSAL


def compose_with_traversal(ctx, kernel: str, module: str | None = None, replacements: dict | None = None) -> str:
    """WGSL of ``kernel`` (which imports accel/bvh.wgsl) with ``module`` (default: traversal_module(ctx)) and
    any further module ``replacements`` (shaders.compose)."""
    return shaders.compose(kernel, replacements={**(replacements or {}),
                                                 LANES_TRAVERSAL: module or traversal_module(ctx)})
