"""GeometryBuffers: a Scene at one frame as world-space triangles in BVH order (bind group 0), and
InstancedGeometry: a Scene with moving meshes or instanced shapes as two BVH levels that follow the frames.

See ARCHITECTURE.md, "Geometry". The GPU layout, in binding order, matches wgsl/accel/geometry_bindings.wgsl:

0. ``bvh_nodes``: the BVH's 32-byte threaded nodes, one depth-first copy per direction octant
   (``wgpu_rt.accel.bvh.ordered_threaded_nodes``), or with layout "wide" its 112-byte 4-wide nodes
   (``wgpu_rt.accel.bvh.wide_nodes``); two-level: see InstancedGeometry.
1. ``tri_positions``: three vec4f per triangle (xyz = world vertex, two-level: in the space of the
   triangle's bottom level; w = the vertex's colour as 8-bit sRGB, R in the low byte, its bits stored as
   the float's: white where the mesh has none; the w words were spare, so colours cost no memory).
2. ``tri_attributes``: per triangle ``{n0, material, n1, object, n2, unused}`` (48 bytes): the three
   shading normals (the mesh's vertex normals, else its face normal; two-level: in the bottom level's
   space, zero for meshes without vertex normals) and the ids (two-level: an instance's own override
   them, except the world-space level's).
3. ``object_motion``: one column-major mat4x4f per object (mesh index): world at this frame → world
   at the previous frame; where a mesh bends, each triangle's world vertices at the previous frame instead
   (``previous_triangles``, three vec4f a triangle).
4. two-level only: ``instances``, INSTANCE_DTYPE per instance (wgsl/accel/instances.wgsl).
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import os
from dataclasses import dataclass

import numpy as np

from .. import shaders
from .bvh import (
    LEAF_COUNT_BITS,
    ORDERINGS,
    QUANTIZED_WIDE_NODE_WORDS,
    SMALL_LEAF_TRAVERSAL_COST,
    THREADED_NODE_DTYPE,
    TRAVERSAL_COST,
    WIDE_EMPTY,
    WIDE_LEAF,
    WIDE_NODE_DTYPE,
    Bvh,
    build_box_bvh,
    build_bvh,
    ordered_threaded_nodes,
    quantized_wide_nodes,
    wide_nodes,
)
from ..errors import SceneError
from ..scene.model import ALPHA_MODES, Scene, srgb8
from ..scene.transforms import transform_normals, transform_points


# accel/bvh.wgsl imports NO_INSTANCES; a two-level scene's kernels swap in InstancedGeometry.instances_module.
NO_INSTANCES = "accel/instances_none.wgsl"
LEAF_MASK = (1 << LEAF_COUNT_BITS) - 1
# accel/bvh.wgsl imports THREADED_WALK; a geometry's walk_module names the one its node layout needs.
THREADED_WALK = "accel/walk_threaded.wgsl"
WIDE_WALK = "accel/walk_wide.wgsl"
# accel/bvh.wgsl imports MOTION_OBJECTS (binding 3: a matrix an object); a geometry whose meshes bend swaps in
# MOTION_VERTICES (binding 3: each triangle's vertices at the frame before).
MOTION_OBJECTS = "accel/motion_objects.wgsl"
MOTION_VERTICES = "accel/motion_vertices.wgsl"
# layout -> the module that walks it; "wide8" is "wide" with its boxes quantized to 8 bits (64-byte nodes)
BVH_LAYOUTS = {"threaded": THREADED_WALK, "wide": WIDE_WALK, "wide8": WIDE_WALK}
# accel/walk_wide.wgsl imports WIDE_NODE_FULL; layout "wide8" swaps in QUANTIZED_WIDE_NODE
WIDE_NODE_FULL = "accel/wide_node_full.wgsl"
QUANTIZED_WIDE_NODE = "accel/wide_node_quantized.wgsl"
BVH_LAYOUT_ENV = "WGPU_RT_BVH"


# A variant's suffix: the nodes and triangle positions fetched as 16-byte rows, one vector load each
# (accel/geometry_rows.wgsl), by the per-invocation traversal (accel/traversal_lanes.wgsl).
ROW_LOADS = "+rows"
# A variant's infix (before ROW_LOADS): the BVH built with small leaves (bvh.SMALL_LEAF_TRAVERSAL_COST),
# offered beside the per-invocation traversal for the wide layouts.
SMALL_LEAVES = "+small-leaves"


def split_variant(variant: str) -> tuple[str, bool, bool]:
    """A BVH variant's (node layout, small leaves, row loads); ValueError for one that names no layout."""
    rest = variant.removesuffix(ROW_LOADS)
    layout = rest.removesuffix(SMALL_LEAVES)
    if layout not in BVH_LAYOUTS:
        raise ValueError(f"unknown BVH variant {variant!r}")
    return layout, rest != layout, rest != variant


def variant_name(layout: str, small_leaves: bool, row_loads: bool) -> str:
    return layout + SMALL_LEAVES * small_leaves + ROW_LOADS * row_loads


def leaf_traversal_cost(small_leaves: bool) -> float:
    """The SAH's node visit cost a tree is built with."""
    return SMALL_LEAF_TRAVERSAL_COST if small_leaves else TRAVERSAL_COST


def geometry_modules(geometry) -> dict:
    """The module swaps for kernels that trace ``geometry``: its instances and walk modules, and its
    geometry words module where it is fetched as rows."""
    modules = {NO_INSTANCES: geometry.instances_module, THREADED_WALK: geometry.walk_module}
    if getattr(geometry, "previous_triangles", None) is not None:
        modules[MOTION_OBJECTS] = MOTION_VERTICES
    if geometry.row_loads:
        modules[GEOMETRY_WORDS] = GEOMETRY_ROWS
    if geometry.layout == "wide8":
        modules[WIDE_NODE_FULL] = QUANTIZED_WIDE_NODE
    return modules


def wide_node_bytes(layout: str) -> int:
    """Bytes of one node of a wide ``layout`` in binding 0: 112 ("wide"), or 64 quantized ("wide8")."""
    return 4 * QUANTIZED_WIDE_NODE_WORDS if layout == "wide8" else WIDE_NODE_DTYPE.itemsize


def bvh_variants(traversal: str) -> list[str]:
    """The ways a single-level scene can be laid out and fetched for ``traversal`` (what bvh_choice
    measures): the threaded and the wide layout, the wide one also built with small leaves (SMALL_LEAVES),
    and beside the per-invocation traversal also "wide8" (whose nodes each invocation decodes for itself,
    where a subgroup packet would fetch them together), with and without small leaves, and each variant
    fetched as rows (a subgroup packet fetches words). Any of them traces correctly with either
    traversal."""
    if traversal != LANES_TRAVERSAL:
        return ["threaded", "wide", variant_name("wide", True, False)]
    return [variant_name(layout, small_leaves, rows) for rows in (False, True) for small_leaves in (False, True)
            for layout in BVH_LAYOUTS if layout != "threaded" or not small_leaves]


def bvh_layout() -> str:
    """The BVH variant single-level scenes are built with, from WGPU_RT_BVH: "auto" (the default: the
    fastest on this adapter, measured once per scene size; wgpu_rt.trace.bvh_choice), "threaded" (the
    stackless binary walk, fast with lavapipe's subgroup packets) or "wide" (a 4-wide tree walked with a
    stack, nearest child first), "wide8" (its boxes quantized), the wide ones also built with SMALL_LEAVES,
    any with ROW_LOADS ("wide+small-leaves+rows")."""
    layout = os.environ.get(BVH_LAYOUT_ENV, "auto")
    if layout != "auto" and layout not in bvh_variants(LANES_TRAVERSAL):
        raise SceneError(f"{BVH_LAYOUT_ENV}={layout!r}: the BVH layout must be auto or one of "
                         f"{', '.join(bvh_variants(LANES_TRAVERSAL))}")
    return layout


def scene_material_names(scene: Scene) -> list[str]:
    """Material names in material-id order (the order of ``scene.materials``)."""
    return list(scene.materials)


def _face_normals(triangles: np.ndarray) -> np.ndarray:
    """Unit normals of (T, 3, 3) triangles by winding; +z for zero-area ones (which never get hit)."""
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]).astype(np.float64)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.where(length > 0, normals / np.where(length > 0, length, 1.0), [0.0, 0.0, 1.0]).astype(np.float32)


WHITE = 0x00FFFFFF   # a packed vertex colour of 1, 1, 1: the material's reflectance as it is


def _mesh_colors(mesh) -> np.ndarray:
    """(F, 3) u32: each face's vertex colours packed as 8-bit sRGB (R in the low byte), WHITE without any."""
    faces = np.asarray(mesh.faces, np.int64)
    if mesh.colors is None:
        return np.full(faces.shape, WHITE, np.uint32)
    colors = np.asarray(mesh.colors)
    if colors.shape != np.shape(mesh.vertices) or not np.all(np.isfinite(colors)):
        raise SceneError(f"mesh {mesh.name!r}: colors must be finite, one RGB a vertex ({np.shape(mesh.vertices)}), "
                         f"got shape {colors.shape}")
    codes = srgb8(colors).astype(np.uint32)
    return (codes[:, 0] | codes[:, 1] << 8 | codes[:, 2] << 16)[faces]


NO_TEXTURE = 0xFFFFFFFF   # a triangle record's texture index where its mesh has none (in its maps' word: neither)
TEXTURE_RECORD_WORDS = 8  # per triangle: texture index, (u, v) of its three vertices, normal and metal-rough maps
# A record's last word holds two image indices: its normal map's in the low half, its metal-rough map's in the high
# half, each NO_MAP where the mesh has none (so NO_TEXTURE there means neither); a scene has at most NO_MAP images.
NO_MAP = 0xFFFF
CUTOUT_FLAG = 0x80000000  # on a record's texture index: its alpha cuts the surface away (wgsl/trace/cutouts.wgsl)
BLEND_FLAG = 0x40000000   # with CUTOUT_FLAG: stochastically, alpha the probability of a surface there
# accel/walk_tree.wgsl imports NO_CUTOUTS; a path-tracing kernel of a scene with cut-out surfaces swaps in the
# module that reads their textures (wgpu_rt.trace.trace_pass.CUTOUTS).
NO_CUTOUTS = "accel/cutouts_none.wgsl"


def _check_image(mesh, image, what: str, channels: tuple[int, ...] = (3,)) -> None:
    image = np.asarray(image)
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] not in channels or min(image.shape[:2]) == 0:
        shapes = " or ".join(f"(H, W, {c})" for c in channels)
        raise SceneError(f"mesh {mesh.name!r}: {what} must be an {shapes} uint8 image, got {image.dtype} "
                         f"{image.shape}")


def has_cutouts(records: np.ndarray | None) -> bool:
    """Whether any of the texture ``records`` (_mesh_texture_records) cuts its surface away."""
    if records is None:
        return False
    textures = records[:, 0]
    return bool(np.any((textures != NO_TEXTURE) & (textures & CUTOUT_FLAG != 0)))


def _mesh_texture_records(mesh, textures: dict[int, int]) -> np.ndarray:
    """(F, TEXTURE_RECORD_WORDS) u32 per face: the index in ``textures`` (image id → index; NO_TEXTURE without
    one) of its mesh's texture, with CUTOUT_FLAG where the texture has an alpha channel (which cuts the surface
    away; BLEND_FLAG too where the mesh's alpha_mode is "blend"), its vertices' texture coordinates as float32
    bits, and the indices of its mesh's normal map and metal-rough map (NO_MAP where it has none; SceneError where an
    image or the coordinates are malformed, naming the mesh)."""
    faces = np.asarray(mesh.faces, np.int64)
    records = np.zeros((len(faces), TEXTURE_RECORD_WORDS), np.uint32)
    records[:, [0, 7]] = NO_TEXTURE
    has_image = any(image is not None for image in (mesh.texture, mesh.normal_map, mesh.emission_texture,
                                                      mesh.metal_rough_map))
    if has_image != (mesh.uvs is not None):
        raise SceneError(f"mesh {mesh.name!r}: a texture, normal map, emission texture or metal-rough map needs its "
                         f"coordinates (uvs), and coordinates one of them")
    if not has_image:
        return records
    uvs = np.asarray(mesh.uvs)
    if uvs.shape != (len(mesh.vertices), 2) or not np.all(np.isfinite(uvs)):
        raise SceneError(f"mesh {mesh.name!r}: uvs must be finite, one (u, v) a vertex "
                         f"({len(mesh.vertices)}, 2), got shape {uvs.shape}")
    if mesh.texture is not None:
        _check_image(mesh, mesh.texture, "texture", channels=(3, 4))
        if mesh.colors is not None:
            raise SceneError(f"mesh {mesh.name!r}: has both vertex colours and a texture; give it one of them")
        if mesh.alpha_mode not in ALPHA_MODES:
            raise SceneError(f"mesh {mesh.name!r}: alpha_mode must be one of {ALPHA_MODES}, got {mesh.alpha_mode!r}")
        flags = (CUTOUT_FLAG | (BLEND_FLAG if mesh.alpha_mode == "blend" else 0)) if mesh.is_cut_out else 0
        records[:, 0] = textures[id(mesh.texture)] | flags
    if mesh.emission_texture is not None:
        _check_image(mesh, mesh.emission_texture, "emission_texture")
    if len(textures) > NO_MAP:
        raise SceneError(f"a scene may have at most {NO_MAP} images (textures and maps), this one has {len(textures)}")
    maps = [NO_MAP, NO_MAP]
    for slot, (image, what) in enumerate(((mesh.normal_map, "normal_map"), (mesh.metal_rough_map, "metal_rough_map"))):
        if image is not None:
            _check_image(mesh, image, what)
            maps[slot] = textures[id(image)]
    records[:, 7] = maps[0] | maps[1] << 16
    records[:, 1:7] = uvs.astype(np.float32)[faces].reshape(len(faces), 6).view(np.uint32)
    return records


def _scene_texture_records(scene: Scene, meshes) -> np.ndarray | None:
    """Per triangle of ``meshes`` (indices into scene.meshes, in order) its texture record
    (_mesh_texture_records), or None where the scene has no texture."""
    textures = {id(image): index for index, image in enumerate(scene.textures())}
    if not textures and all(scene.meshes[i].uvs is None for i in meshes):
        return None
    return np.concatenate([_mesh_texture_records(scene.meshes[i], textures) for i in meshes])


def _mesh_triangles(mesh, transform: np.ndarray, frame: int, face_normals: bool = True) -> tuple[np.ndarray,
                                                                                                 np.ndarray]:
    """``mesh``'s triangles (F, 3, 3) and per-vertex shading normals (F, 3, 3) in its shape at ``frame``, both
    mapped by ``transform`` (object → the space they are stored in). A mesh without vertex normals gets its face
    normals, or with ``face_normals`` False zeros, which the kernels replace by the geometric normal
    (an instance's world normal follows its world winding, which a mirroring transform reverses)."""
    faces = np.asarray(mesh.faces, np.int64)
    transform = np.asarray(transform, np.float64)
    triangles = transform_points(transform, mesh.vertices_at(frame))[faces]
    normals = mesh.normals_at(frame)
    if normals is None:
        normals = np.repeat(_face_normals(triangles)[:, None] * face_normals, 3, axis=1)
    else:
        normals = transform_normals(transform, normals)[faces]
    return triangles, normals


def _material_ids(scene: Scene) -> list[int]:
    """Per mesh, its material's index in scene_material_names(scene) (SceneError if unknown)."""
    material_index = {name: i for i, name in enumerate(scene_material_names(scene))}
    for mesh in scene.meshes:
        if mesh.material not in material_index:
            raise SceneError(f"scene {scene.name!r}: mesh {mesh.name!r}: unknown material {mesh.material!r}")
    return [material_index[mesh.material] for mesh in scene.meshes]


def object_motion(scene: Scene, frame: int) -> np.ndarray:
    """(O, 4, 4) f32 per mesh: world at ``frame`` → world at the frame before (a bending mesh's points each move
    their own way: see GeometryBuffers.previous_triangles)."""
    return np.asarray([mesh.transform_at(frame - 1).astype(np.float64)
                       @ np.linalg.inv(mesh.transform_at(frame).astype(np.float64)) for mesh in scene.meshes],
                      np.float32)


def _check_triangles(scene: Scene, triangles: list[np.ndarray]) -> np.ndarray:
    if not triangles or sum(len(t) for t in triangles) == 0:
        raise SceneError(f"scene {scene.name!r}: no triangles to render")
    joined = np.concatenate(triangles)
    if not np.all(np.isfinite(joined)):
        raise SceneError(f"scene {scene.name!r}: a transform produced NaN or infinite vertices")
    return joined


@dataclass
class GeometryBuffers:
    triangles: np.ndarray          # (T, 3, 3) f32 world-space vertices, BVH order
    shading_normals: np.ndarray    # (T, 3, 3) f32 unit world-space normals per vertex
    vertex_colors: np.ndarray      # (T, 3) u32 packed 8-bit sRGB colour per vertex (_mesh_colors)
    material_ids: np.ndarray       # (T,) u32 index into scene_material_names(scene)
    object_ids: np.ndarray         # (T,) u32 index into scene.meshes
    object_motion: np.ndarray      # (O, 4, 4) f32 world at this frame → world at the previous frame
    texture_records: np.ndarray | None   # (T, TEXTURE_RECORD_WORDS) u32 (_mesh_texture_records), None: no texture
    bvh: Bvh
    # (T, 3, 3) f32 world-space vertices at the frame before, BVH order, where a mesh bends (Mesh.vertex_keyframes):
    # binding 3 then holds them in place of object_motion (MOTION_VERTICES). None: every mesh is rigid.
    previous_triangles: np.ndarray | None = None
    layout: str = "threaded"       # binding 0's node layout: a key of BVH_LAYOUTS
    row_loads: bool = False        # kernels fetch nodes and positions as rows (ROW_LOADS)
    small_leaves: bool = False     # ``bvh`` was built with small leaves (SMALL_LEAVES)

    # The kernels' instance module: none (see InstancedGeometry).
    instances_module = NO_INSTANCES

    @property
    def walk_module(self) -> str:
        """The module that walks this geometry's node layout, in place of THREADED_WALK."""
        return BVH_LAYOUTS[self.layout]

    kernel_modules = property(geometry_modules)   # the module swaps its kernels need

    @functools.cached_property
    def wide_nodes(self) -> np.ndarray:
        """The BVH as 4-wide nodes (layout "wide"), collapsed on first use."""
        return wide_nodes(self.bvh)

    def _nodes(self, orderings: int) -> np.ndarray:
        """Binding 0 in this layout: ``orderings`` threaded copies, the wide nodes, or them quantized."""
        if self.layout == "threaded":
            return ordered_threaded_nodes(self.bvh, orderings)
        return quantized_wide_nodes(self.wide_nodes) if self.layout == "wide8" else self.wide_nodes

    @classmethod
    def build(cls, scene: Scene, frame: int = 0, small_leaves: bool = False) -> "GeometryBuffers":
        """``scene``'s triangles at ``frame`` and their BVH (built with small leaves or not), laid out
        threaded (``as_variant`` for others)."""
        material_ids = _material_ids(scene)
        triangles, normals, colors, materials, objects = [], [], [], [], []
        previous = [_mesh_triangles(mesh, mesh.transform_at(frame - 1), frame - 1)[0]
                    for mesh in scene.meshes] if scene.deforms else None
        for object_id, mesh in enumerate(scene.meshes):
            world, shading = _mesh_triangles(mesh, mesh.transform_at(frame), frame)
            triangles.append(world)
            normals.append(shading)
            colors.append(_mesh_colors(mesh))
            materials.append(np.full(len(world), material_ids[object_id], np.uint32))
            objects.append(np.full(len(world), object_id, np.uint32))
        all_triangles = _check_triangles(scene, triangles)
        bvh = build_bvh(all_triangles, leaf_traversal_cost(small_leaves))
        order = bvh.order
        textures = _scene_texture_records(scene, range(len(scene.meshes)))
        return cls(all_triangles[order], np.concatenate(normals)[order], np.concatenate(colors)[order],
                   np.concatenate(materials)[order], np.concatenate(objects)[order], object_motion(scene, frame),
                   None if textures is None else textures[order], bvh,
                   None if previous is None else _check_triangles(scene, previous)[order], small_leaves=small_leaves)

    def as_variant(self, variant: str) -> "GeometryBuffers":
        """This geometry laid out and fetched as ``variant`` (bvh_variants): the same BVH, or where the
        variant's leaves are not this BVH's, one rebuilt with them (``with_leaves``)."""
        layout, small_leaves, row_loads = split_variant(variant)
        return dataclasses.replace(self.with_leaves(small_leaves), layout=layout, row_loads=row_loads)

    def with_leaves(self, small_leaves: bool) -> "GeometryBuffers":
        """This geometry with its BVH built with small leaves or without: itself where it is, else the
        triangles reordered for a BVH rebuilt so (once per geometry; a layout choice asks for it per
        variant)."""
        if small_leaves == self.small_leaves:
            return self
        rebuilt = self.__dict__.setdefault("_rebuilt", {})
        if small_leaves not in rebuilt:
            bvh = build_bvh(self.triangles, leaf_traversal_cost(small_leaves))
            order = bvh.order
            rebuilt[small_leaves] = dataclasses.replace(
                self, triangles=self.triangles[order], shading_normals=self.shading_normals[order],
                vertex_colors=self.vertex_colors[order], material_ids=self.material_ids[order],
                object_ids=self.object_ids[order], bvh=bvh, small_leaves=small_leaves,
                texture_records=None if self.texture_records is None else self.texture_records[order],
                previous_triangles=None if self.previous_triangles is None else self.previous_triangles[order])
        return rebuilt[small_leaves]

    @property
    def variant(self) -> str:
        return variant_name(self.layout, self.small_leaves, self.row_loads)

    @property
    def triangle_count(self) -> int:
        return len(self.triangles)

    def orderings(self, ctx) -> int:
        """Direction-ordered node copies to upload: ORDERINGS, or 1 (the walk then takes copy 0 for every
        direction: correct, just less culling) when ORDERINGS copies exceed one storage binding."""
        node_bytes = self.bvh.node_count * THREADED_NODE_DTYPE.itemsize
        limit = ctx.binding_limit
        return ORDERINGS if ORDERINGS * node_bytes <= limit else 1

    def packed_arrays(self, orderings: int = ORDERINGS) -> list[np.ndarray]:
        """The four arrays of bind group 0, laid out byte for byte as wgsl/accel/bvh.wgsl reads them."""
        positions, attributes = _pack_triangles(self.triangles, self.shading_normals, self.vertex_colors,
                                                self.material_ids, self.object_ids)
        if self.previous_triangles is None:
            motion = _column_major(self.object_motion)
        else:
            motion = np.zeros((len(self.previous_triangles) * 3, 4), np.float32)
            motion[:, :3] = self.previous_triangles.reshape(-1, 3)
        return [self._nodes(orderings), positions, attributes, motion]

    @property
    def fits_uniform(self) -> bool:
        """Whether the nodes and positions fit UNIFORM_GEOMETRY_WORDS' buffers."""
        node_bytes = (ORDERINGS * self.bvh.node_count * THREADED_NODE_DTYPE.itemsize if self.layout == "threaded"
                      else len(self.wide_nodes) * wide_node_bytes(self.layout))   # sized, not packed
        return _fits_uniform(node_bytes, self.triangle_count)

    def upload(self, ctx, uniform_words: bool = False) -> list:
        """GPU buffers in binding order 0..3 of group 0 (DeviceLimitError if one is too big): all storage,
        or (``uniform_words``, for kernels composed with UNIFORM_GEOMETRY_WORDS) the nodes and positions
        in zero-padded uniform buffers."""
        if uniform_words and not self.fits_uniform:
            raise ValueError(f"{self.triangle_count} triangles exceed the uniform geometry buffers")
        return _upload(ctx, self.packed_arrays(self.orderings(ctx)), self.triangle_count, uniform_words)


GEOMETRY_LABELS = ("BVH nodes", "triangle positions", "triangle attributes", "object motion", "instances")


def _upload(ctx, arrays: list[np.ndarray], triangle_count: int, uniform_words: bool) -> list:
    """``arrays`` (bind group 0 in binding order) as GPU buffers, the first two in zero-padded uniform
    buffers with ``uniform_words``."""
    labels = GEOMETRY_LABELS[:len(arrays)]
    for array, label in zip(arrays, labels):
        ctx.check_buffer_size(array.nbytes, f"{label} ({triangle_count} triangles)")
    buffers = [ctx.upload(array, label=label) for array, label in zip(arrays[2:], labels[2:])]
    if not uniform_words:
        return [ctx.upload(array, label=label) for array, label in zip(arrays[:2], labels[:2])] + buffers
    words = [array.tobytes().ljust(UNIFORM_GEOMETRY_BYTES, b"\0") for array in arrays[:2]]
    return [ctx.uniform(data, label=label) for data, label in zip(words, labels[:2])] + buffers


def _fits_uniform(node_bytes: int, triangle_count: int) -> bool:
    return max(node_bytes, triangle_count * POSITION_BYTES) <= UNIFORM_GEOMETRY_BYTES


def _pack_triangles(triangles, shading_normals, vertex_colors, material_ids, object_ids):
    """Bindings 1 and 2: positions (T, 3, 4) f32, each vertex's packed colour in its w word's bits, and
    attributes (T, 12) words (the last one unused)."""
    count = len(triangles)
    positions = np.zeros((count, 3, 4), np.float32)
    positions[..., :3] = triangles
    positions.view(np.uint32)[..., 3] = vertex_colors
    attributes = np.zeros((count, 12), np.float32)
    attributes[:, [0, 1, 2, 4, 5, 6, 8, 9, 10]] = shading_normals.reshape(count, 9)
    attributes_u32 = attributes.view(np.uint32)
    attributes_u32[:, 3], attributes_u32[:, 7] = material_ids, object_ids
    return positions, attributes


def _column_major(matrices: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(np.transpose(matrices, (0, 2, 1)))


# Instance records (wgsl/accel/geometry_bindings.wgsl, Instance): mat4x3f and mat3x3f columns are vec3f
# padded to 16 bytes; then the number of its first placed triangle, where its bottom level's triangles
# start, and its material and object (FROM_TRIANGLE: each triangle's own, as the world-space level's).
INSTANCE_DTYPE = np.dtype([("to_world", "<f4", (4, 4)), ("normal_to_world", "<f4", (3, 4)), ("first_prim", "<u4"),
                           ("first_triangle", "<u4"), ("material", "<u4"), ("object", "<u4")])
FROM_TRIANGLE = 0xFFFFFFFF
PLACED_TRIANGLE_LIMIT = 0xFFFFFFFF      # placed triangles are numbered below Hit's NO_HIT (a miss)
# A top-level box is widened by this much of its size so that rounding in the corners' transform (and
# in the ray's on the GPU) never cuts off an instance's edge.
INSTANCE_BOX_PADDING = 1e-5


class InstancedGeometry:
    """A scene as two levels (ARCHITECTURE.md, "Geometry"): bottom-level BVHs over triangles, each built
    once, and a top-level BVH over their placements (the instances), rebuilt when they move.

    Bottom levels: one per shape placed several times (``Scene.shapes``: meshes sharing their arrays)
    and one per other moving mesh, over its object-space triangles; one over all other meshes (static,
    placed once) in world space. Instances: every placement of a shape and every other moving mesh
    (its mesh's transform), and the world-space level (identity), in that level order. A shape placed
    1000 times is stored once: its triangles and one BVH, plus two entry node slots and one record per
    instance.

    Hits number the placed triangles (``Hit.prim``; ``triangles``, ``material_ids``, ``object_ids`` and
    ``instance_ids`` are in that order): instance after instance, each instance's in its bottom level's
    order, so every placed triangle has a number of its own (the tracer's per-triangle emitter densities
    are indexed by it). Instance i's are ``first_prims[i]`` onward; the GPU finds the instance of a
    number from the records (accel/instances.wgsl, placed_instance).

    Bind group 0 as GeometryBuffers', plus binding 4, the instance records (accel/instances.wgsl):
    ``bvh_nodes`` holds the top level's ORDERINGS copies (always: it is small, and the kernels find its
    copies as they find a single-level tree's) and the instances' entries (``top_level``), then each
    bottom level's ``orderings(ctx)`` copies (its triangles' indices offset to its place in the
    triangle buffers). A frame whose transforms changed rewrites only the top level and entries, the
    instance records and the object motion (``frame_arrays``, ``write_frame``). Where emissive meshes
    move (``moves_emitters``), the tracer rebuilds the emitter table for each frame from
    ``placed_triangles`` (wgpu_rt/trace/trace_pass.py).
    """

    instances_module = "accel/instances.wgsl"
    layout = "threaded"           # the bottom levels' node layout (BVH_LAYOUTS); the top level is threaded
    row_loads = False             # kernels fetch nodes and positions as rows (ROW_LOADS)
    kernel_modules = property(geometry_modules)   # the module swaps its kernels need

    @property
    def walk_module(self) -> str:
        """The module that walks the bottom levels' node layout, in place of THREADED_WALK."""
        return BVH_LAYOUTS[self.layout]

    @property
    def variant(self) -> str:
        return variant_name(self.layout, self.small_leaves, self.row_loads)

    def as_variant(self, variant: str) -> "InstancedGeometry":
        """This geometry with bottom levels laid out and fetched as ``variant`` (bvh_variants): with "wide",
        each bottom level is one 4-wide tree (wgsl/accel/walk_wide.wgsl, walk_bottom_level) instead of
        ORDERINGS threaded copies. The same BVHs, or where the variant's leaves are not theirs, the
        geometry built again with them."""
        layout, small_leaves, row_loads = split_variant(variant)
        other = copy.copy(self) if small_leaves == self.small_leaves else InstancedGeometry(self.scene, self.frame,
                                                                                          small_leaves)
        other.layout, other.row_loads = layout, row_loads
        return other

    def __init__(self, scene: Scene, frame: int = 0, small_leaves: bool = False):
        self.scene, self.small_leaves = scene, small_leaves
        material_ids = _material_ids(scene)
        shapes = [group for group in scene.shapes() if len(scene.meshes[group[0]].faces)]
        if not shapes:
            raise SceneError(f"scene {scene.name!r}: no triangles to render")
        in_world = [group[0] for group in shapes if len(group) == 1 and not scene.meshes[group[0]].is_animated]
        placed = [group for group in shapes if len(group) > 1 or scene.meshes[group[0]].is_animated]
        # Per bottom level: the meshes whose triangles it stores and whether it is in world space; per
        # instance: its bottom level and the mesh that places it (None: the world-space level).
        self.levels = ([(in_world, True)] if in_world else []) + [([group[0]], False) for group in placed]
        self.instance_meshes = ([None] if in_world else []) + [mesh for group in placed for mesh in group]
        self.instance_levels = np.repeat(np.arange(len(self.levels)),
                                         ([1] if in_world else []) + [len(group) for group in placed])
        stored, normals, colors, materials, objects, self._bvhs, textures = ([] for _ in range(7))
        for meshes, world_space in self.levels:
            level = [_mesh_triangles(scene.meshes[i], scene.meshes[i].transform_at(frame) if world_space
                                     else np.eye(4), frame, face_normals=False) for i in meshes]
            triangles = _check_triangles(scene, [t for t, _ in level])
            bvh = build_bvh(triangles, leaf_traversal_cost(small_leaves))
            order = bvh.order
            stored.append(triangles[order])
            normals.append(np.concatenate([n for _, n in level])[order])
            colors.append(np.concatenate([_mesh_colors(scene.meshes[i]) for i in meshes])[order])
            materials.append(np.repeat([material_ids[i] for i in meshes], [len(t) for t, _ in level])[order])
            objects.append(np.repeat(meshes, [len(t) for t, _ in level])[order])
            records = _scene_texture_records(scene, meshes)
            textures.append(None if records is None else records[order])
            self._bvhs.append(bvh)
        self._level_sizes = np.array([len(t) for t in stored], np.int64)
        self._first_triangles = np.cumsum(self._level_sizes) - self._level_sizes
        if self._level_sizes.sum() >= 1 << (32 - LEAF_COUNT_BITS):
            raise SceneError(f"scene {scene.name!r}: {self._level_sizes.sum()} triangles do not fit the node "
                             f"layout")
        if len(self.instance_meshes) >= 1 << (32 - LEAF_COUNT_BITS):
            raise SceneError(f"scene {scene.name!r}: {len(self.instance_meshes)} instances do not fit the node "
                             f"layout")
        self.stored_triangles = np.concatenate(stored)       # (T, 3, 3) f32 in each level's space
        self.shading_normals = np.concatenate(normals)       # (T, 3, 3) f32 in each level's space
        self.vertex_colors = np.concatenate(colors)          # (T, 3) u32 (_mesh_colors)
        self.stored_material_ids = np.concatenate(materials).astype(np.uint32)
        self.stored_object_ids = np.concatenate(objects).astype(np.uint32)
        # (T, TEXTURE_RECORD_WORDS) u32 per stored triangle, None where no mesh has a texture
        self.texture_records = None if textures[0] is None else np.concatenate(textures)

        counts = self._level_sizes[self.instance_levels]     # placed triangles per instance
        self.first_prims = np.cumsum(counts) - counts
        self.placed_triangle_count = int(counts.sum())
        if self.placed_triangle_count >= PLACED_TRIANGLE_LIMIT:
            raise SceneError(f"scene {scene.name!r}: {self.placed_triangle_count} placed triangles exceed "
                             f"the 32-bit triangle numbers")
        self._instance_materials = np.array([FROM_TRIANGLE if mesh is None else material_ids[mesh]
                                             for mesh in self.instance_meshes], np.uint32)
        self._instance_objects = np.array([FROM_TRIANGLE if mesh is None else mesh
                                           for mesh in self.instance_meshes], np.uint32)
        self.instance_ids = np.repeat(np.arange(len(counts), dtype=np.uint32), counts)   # per placed triangle
        stored_index = np.arange(self.placed_triangle_count) + np.repeat(
            self._first_triangles[self.instance_levels] - self.first_prims, counts)

        def per_placed(instance_ids: np.ndarray, triangle_ids: np.ndarray) -> np.ndarray:
            """Per placed triangle: its instance's id, or its stored triangle's where that is FROM_TRIANGLE."""
            own = instance_ids[self.instance_ids]
            return np.where(own == FROM_TRIANGLE, triangle_ids[stored_index], own)

        self.material_ids = per_placed(self._instance_materials, self.stored_material_ids)
        self.object_ids = per_placed(self._instance_objects, self.stored_object_ids)
        self._root_boxes = np.array([[bvh.nodes["lo"][0], bvh.nodes["hi"][0]] for bvh in self._bvhs],
                                    np.float64)                                            # (L, 2, 3)
        self._hittable = np.flatnonzero(np.all(np.isfinite(self._root_boxes[self.instance_levels]), axis=(1, 2)))
        self.top_node_count = max(1, 2 * len(self._hittable) - 1)
        self._node_counts = np.array([bvh.node_count for bvh in self._bvhs])
        self.frame = frame

    @staticmethod
    def suits(scene: Scene) -> bool:
        """Whether ``scene`` has a moving mesh or a shape placed several times (a moving emitter too: the
        tracer's emitter table follows it, wgpu_rt.trace.TracePass.set_frame), and no mesh that changes shape
        (the bottom levels are built once: a deforming scene is built anew in one level at every frame)."""
        return not scene.deforms and (scene.has_instances or any(mesh.is_animated for mesh in scene.meshes))

    @staticmethod
    def moves_emitters(scene: Scene) -> bool:
        """Whether an emissive mesh of ``scene`` moves (then its emitter table changes every frame)."""
        return any(mesh.is_animated and mesh.material in scene.materials
                   and scene.materials[mesh.material].is_emissive for mesh in scene.meshes)

    @property
    def triangle_count(self) -> int:
        """Triangles stored (each shape's once), which the GPU buffers hold."""
        return len(self.stored_triangles)

    @functools.cached_property
    def triangles(self) -> np.ndarray:
        """(P, 3, 3) f32 world-space placed triangles at ``frame``, by number (the tracer builds its emitter
        table from them)."""
        return self.world_triangles(self.frame)

    def instance_transforms(self, frame: int) -> np.ndarray:
        """(I, 4, 4) f64 object → world per instance at ``frame`` (identity for the world-space level)."""
        return np.array([np.eye(4) if mesh is None else self.scene.meshes[mesh].transform_at(frame)
                         for mesh in self.instance_meshes], np.float64)

    def transform_key(self, frame: int) -> bytes:
        """What ``frame_arrays(frame)`` depends on: the transforms at ``frame`` and the frame before."""
        return b"".join(m.transform_at(f).tobytes() for f in (frame, frame - 1) for m in self.scene.meshes)

    def world_triangles(self, frame: int) -> np.ndarray:
        """(P, 3, 3) f32 world-space vertices of the placed triangles at ``frame``, by number."""
        world = np.empty((self.placed_triangle_count, 3, 3), np.float32)
        transforms = self.instance_transforms(frame)
        for level, (first, size) in enumerate(zip(self._first_triangles, self._level_sizes)):
            mine = np.flatnonzero(self.instance_levels == level)      # consecutive, numbered in order
            points = self.stored_triangles[first:first + size].reshape(-1, 3).astype(np.float64)
            mapped = points @ np.transpose(transforms[mine, :3, :3], (0, 2, 1)) + transforms[mine, None, :3, 3]
            start = self.first_prims[mine[0]]
            world[start:start + len(mine) * size] = mapped.reshape(-1, 3, 3)
        return world

    def placed_triangles(self, frame: int, numbers: np.ndarray) -> np.ndarray:
        """(len(numbers), 3, 3) f32 world-space vertices at ``frame`` of the placed triangles ``numbers``
        (the work follows their count, not the scene's: a moving light's emitter table per frame)."""
        numbers = np.asarray(numbers, np.int64)
        instance = np.searchsorted(self.first_prims, numbers, side="right") - 1
        stored = self._first_triangles[self.instance_levels[instance]] + numbers - self.first_prims[instance]
        transforms = self.instance_transforms(frame)[instance]
        points = self.stored_triangles[stored].astype(np.float64)
        world = np.einsum("tij,tvj->tvi", transforms[:, :3, :3], points) + transforms[:, None, :3, 3]
        return world.astype(np.float32)

    def node_count(self, orderings: int = ORDERINGS) -> int:
        """Node slots in binding 0 with ``orderings`` copies of each threaded bottom level (see top_level)."""
        return ORDERINGS * self.top_node_count + 2 * len(self.instance_meshes) + int(self._level_slots(orderings).sum())

    def _level_slots(self, orderings: int) -> np.ndarray:
        """Node slots (THREADED_NODE_DTYPE's 32 bytes) of each bottom level: ``orderings`` threaded copies,
        or its wide nodes (112 bytes each) rounded up to whole slots."""
        if self.layout != "threaded":
            node_bytes = wide_node_bytes(self.layout)
            return np.array([-(-len(wide) * node_bytes // THREADED_NODE_DTYPE.itemsize) for wide in self._wide_levels],
                            np.int64)
        return orderings * self._node_counts

    @functools.cached_property
    def _wide_levels(self) -> list[np.ndarray]:
        """Each bottom level as 4-wide nodes, its leaves naming triangles where the level's are stored."""
        if self.triangle_count >= 1 << (31 - LEAF_COUNT_BITS):
            raise SceneError(f"scene {self.scene.name!r}: {self.triangle_count} triangles do not fit the wide "
                             f"node layout")
        levels = [wide_nodes(bvh) for bvh in self._bvhs]
        for wide, first_triangle in zip(levels, self._first_triangles):
            children = wide["children"]
            leaf = (children != WIDE_EMPTY) & ((children & WIDE_LEAF) != 0)
            children[leaf] += np.uint32(first_triangle << LEAF_COUNT_BITS)
        return levels

    def _wide_level_nodes(self) -> list[np.ndarray]:
        """The bottom levels' wide nodes as binding 0 holds them: as they are, or quantized ("wide8")."""
        if self.layout == "wide8":
            return [quantized_wide_nodes(wide) for wide in self._wide_levels]
        return self._wide_levels

    def orderings(self, ctx) -> int:
        """Direction-ordered copies of each threaded bottom level to upload: ORDERINGS, or 1 where that
        many exceed one storage binding (as GeometryBuffers.orderings); wide ones have none."""
        limit = ctx.binding_limit
        fits = self.node_count() * THREADED_NODE_DTYPE.itemsize <= limit
        return ORDERINGS if fits and self.layout == "threaded" else 1

    def bottom_nodes(self, orderings: int = ORDERINGS) -> np.ndarray:
        """Every bottom level's nodes, one level after another, as 32-byte slots: ``orderings`` threaded
        copies, or its wide nodes (zero-padded to whole slots)."""
        if self.layout != "threaded":
            slot = THREADED_NODE_DTYPE.itemsize
            return np.frombuffer(b"".join(wide.tobytes().ljust(-(-wide.nbytes // slot) * slot, b"\0")
                                          for wide in self._wide_level_nodes()), THREADED_NODE_DTYPE)
        nodes = [ordered_threaded_nodes(bvh, orderings) for bvh in self._bvhs]
        for threaded, first_triangle in zip(nodes, self._first_triangles):
            threaded["triangles"] += np.uint32(first_triangle << LEAF_COUNT_BITS)
        return np.concatenate(nodes)

    def top_level(self, frame: int, orderings: int = ORDERINGS) -> tuple[np.ndarray, np.ndarray]:
        """The start of binding 0 at ``frame`` and the instance records (binding 4), for bottom levels of
        ``orderings`` copies. The nodes: the top level's ORDERINGS threaded copies (a leaf's triangles
        word is ``(instance << LEAF_COUNT_BITS) | 1``), then two slots per instance, its entry: the
        columns of world → object with, in their fourth words, its bottom level's first node, node count
        and copies (the walk fetches them as it fetches nodes; wgsl/accel/bvh.wgsl, instance_entry)."""
        transforms = self.instance_transforms(frame)
        if not np.all(np.isfinite(transforms)):
            raise SceneError(f"scene {self.scene.name!r}: a transform at frame {frame} is not finite")
        inverse = np.linalg.inv(transforms)
        records = np.zeros(len(self.instance_meshes), INSTANCE_DTYPE)
        records["to_world"][:, :, :3] = np.transpose(transforms[:, :3, :4], (0, 2, 1))
        records["normal_to_world"][:, :, :3] = inverse[:, :3, :3]   # columns of the inverse transpose
        records["first_prim"] = self.first_prims
        records["first_triangle"] = self._first_triangles[self.instance_levels]
        records["material"], records["object"] = self._instance_materials, self._instance_objects
        entries = np.zeros((len(self.instance_meshes), 4, 4), np.float32)
        entries[:, :, :3] = np.transpose(inverse[:, :3, :4], (0, 2, 1))
        level_nodes = self._level_slots(orderings)
        level_first_node = self.node_count(orderings) - level_nodes.sum() + np.cumsum(level_nodes) - level_nodes
        words = entries.view(np.uint32)
        words[:, 0, 3] = level_first_node[self.instance_levels]
        words[:, 1, 3], words[:, 2, 3] = self._node_counts[self.instance_levels], orderings
        entry_nodes = entries.reshape(-1).view(THREADED_NODE_DTYPE)
        if len(self._hittable) == 0:    # no triangle with area: a root no ray enters (as build_bvh's)
            top = np.zeros(ORDERINGS, THREADED_NODE_DTYPE)
            top["lo"], top["hi"], top["skip"] = np.inf, np.inf, 1
            return np.concatenate([top, entry_nodes]), records
        corners = np.array(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij")).reshape(3, 8).T   # (8, 3)
        boxes = self._root_boxes[self.instance_levels[self._hittable]]                      # (H, 2, 3)
        points = boxes[:, corners, [0, 1, 2]]                                               # (H, 8, 3)
        mapped = points @ np.transpose(transforms[self._hittable, :3, :3], (0, 2, 1)) \
            + transforms[self._hittable, None, :3, 3]
        lo, hi = mapped.min(axis=1), mapped.max(axis=1)
        pad = INSTANCE_BOX_PADDING * np.maximum(np.max(hi - lo, axis=1, keepdims=True),
                                                np.max(np.abs(mapped), axis=(1, 2))[:, None])
        bvh = build_box_bvh(np.nextafter((lo - pad).astype(np.float32), -np.inf),
                            np.nextafter((hi + pad).astype(np.float32), np.inf))
        top = ordered_threaded_nodes(bvh)
        owned = top["triangles"]
        leaf = (owned & LEAF_MASK) != 0
        top["triangles"][leaf] = (self._hittable[bvh.order[owned[leaf] >> LEAF_COUNT_BITS]].astype(np.uint32)
                                  << LEAF_COUNT_BITS) | 1
        return np.concatenate([top, entry_nodes]), records

    def frame_arrays(self, frame: int, orderings: int = ORDERINGS) -> list[np.ndarray]:
        """What a frame changes: the top-level nodes (the start of binding 0), the object motion
        (binding 3) and the instance records (binding 4)."""
        top, records = self.top_level(frame, orderings)
        return [top, _column_major(object_motion(self.scene, frame)), records]

    def packed_arrays(self, orderings: int = ORDERINGS) -> list[np.ndarray]:
        """The five arrays of bind group 0 at ``self.frame``."""
        top, motion, records = self.frame_arrays(self.frame, orderings)
        positions, attributes = _pack_triangles(self.stored_triangles, self.shading_normals, self.vertex_colors,
                                                self.stored_material_ids, self.stored_object_ids)
        return [np.concatenate([top, self.bottom_nodes(orderings)]), positions, attributes, motion, records]

    @property
    def fits_uniform(self) -> bool:
        """Whether the nodes and positions fit UNIFORM_GEOMETRY_WORDS' buffers."""
        return _fits_uniform(self.node_count() * THREADED_NODE_DTYPE.itemsize, self.triangle_count)

    def upload(self, ctx, uniform_words: bool = False) -> list:
        """GPU buffers in binding order 0..4 of group 0 (see GeometryBuffers.upload)."""
        if uniform_words and not self.fits_uniform:
            raise ValueError(f"{self.triangle_count} triangles exceed the uniform geometry buffers")
        return _upload(ctx, self.packed_arrays(self.orderings(ctx)), self.triangle_count, uniform_words)

    def write_frame(self, ctx, buffers: list, frame: int) -> None:
        """Point ``buffers`` (from ``upload``) at ``frame``: queue writes of the per-frame arrays only."""
        top, motion, records = self.frame_arrays(frame, self.orderings(ctx))
        for buffer, array in ((buffers[0], top), (buffers[3], motion), (buffers[4], records)):
            ctx.device.queue.write_buffer(buffer, 0, np.ascontiguousarray(array).tobytes())


# accel/geometry_bindings.wgsl imports GEOMETRY_WORDS (storage); kernels whose geometry fits may swap in
# UNIFORM_GEOMETRY_WORDS (uniform buffers of UNIFORM_GEOMETRY_BYTES each, its array sizes).
GEOMETRY_WORDS = "accel/geometry_words.wgsl"
UNIFORM_GEOMETRY_WORDS = "accel/geometry_words_uniform.wgsl"
GEOMETRY_ROWS = "accel/geometry_rows.wgsl"   # storage, as rows (ROW_LOADS)
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
