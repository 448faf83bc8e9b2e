// Bind group 0: the scene's geometry as wgpu_rt/scene/geometry.py lays it out, and the records the
// two traversal modules (accel/traversal_lanes.wgsl, accel/traversal_subgroup.wgsl) fetch from it for accel/bvh.wgsl.
// Buffers are read as flat 32-bit words so that a subgroup can fetch one record cooperatively; the
// nodes and triangle positions through bvh_word / position_word of accel/geometry_words.wgsl (storage
// buffers), which wgpu_rt.scene.geometry swaps for accel/geometry_words_uniform.wgsl when they fit.

// #import accel/geometry_words.wgsl

const NODE_WORDS: u32 = 8u;        // wgpu_rt.bvh.THREADED_NODE_DTYPE
const TRIANGLE_WORDS: u32 = 12u;   // three (x, y, z, colour) vertices: the colour's 8-bit sRGB bits in w
const LEAF_COUNT_BITS: u32 = 4u;   // == wgpu_rt.bvh.LEAF_COUNT_BITS
const LEAF_COUNT_MASK: u32 = 15u;

// A threaded BVH node (wgpu_rt.bvh.threaded_nodes): entering it moves to the next node (its first
// child, or past a leaf), missing it to `skip`, the node after its subtree. `triangles` is
// (first << LEAF_COUNT_BITS) | count of the triangles tested on entering it (interior nodes: 0 or 1).
struct BvhNode { lo: vec3f, skip: u32, hi: vec3f, triangles: u32 }
// A 4-wide node (wgpu_rt.accel.bvh.wide_nodes, WIDE_NODE_WORDS words): one coordinate of its four
// children's boxes per row (child k in component k), then their references (accel/walk_wide.wgsl).
struct WideNode { lo_x: vec4f, lo_y: vec4f, lo_z: vec4f, hi_x: vec4f, hi_y: vec4f, hi_z: vec4f, children: vec4u }
const WIDE_NODE_WORDS: u32 = 28u;   // == wgpu_rt.accel.bvh.WIDE_NODE_DTYPE's size in words
struct TrianglePositions { a: vec3f, b: vec3f, c: vec3f }
// Per stored triangle: shading normals (in its bottom level's space) and ids. In a two-level scene a
// stored triangle may be placed many times, and its instance's material and object override these.
struct TriAttributes { n0: vec3f, material: u32, n1: vec3f, object: u32, n2: vec3f, _unused: u32 }
// What a hit on an instance needs (wgpu_rt.accel.geometry.INSTANCE_DTYPE): its object → world transform
// and the inverse transpose of its linear part, for normals; the number of its first placed triangle
// (a Hit's prim) and where its bottom level's stored triangles start (placed triangle first_prim + k is
// stored triangle first_triangle + k); its material and object, or FROM_TRIANGLE where each triangle's
// own apply (the world-space level). (The walk's world → object transform and where the bottom level's
// nodes are come with the nodes: accel/bvh.wgsl, instance_entry.)
struct Instance { to_world: mat4x3f, normal_to_world: mat3x3f, first_prim: u32, first_triangle: u32,
                  material: u32, object: u32 }
const NO_INSTANCE: u32 = 0xffffffffu;
const FROM_TRIANGLE: u32 = 0xffffffffu;

@group(0) @binding(2) var<storage, read> tri_attributes: array<TriAttributes>;
// (binding 3, what motion vectors read, is declared by accel/motion_objects.wgsl or accel/motion_vertices.wgsl)

// Bit k set where dir's component k is negative: the node copy (wgpu_rt.bvh.ordered_threaded_nodes)
// whose order suits rays of that direction.
fn direction_octant(dir: vec3f) -> u32 {
    return select(0u, 1u, dir.x < 0.0) | select(0u, 2u, dir.y < 0.0) | select(0u, 4u, dir.z < 0.0);
}

// Vertex k of triangle `prim`, read by this invocation alone.
fn triangle_vertex(prim: u32, k: u32) -> vec3f {
    let at = TRIANGLE_WORDS * prim + 4u * k;
    return vec3f(position_word(at), position_word(at + 1u), position_word(at + 2u));
}
