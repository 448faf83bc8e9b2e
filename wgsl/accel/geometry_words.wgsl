// The BVH nodes and triangle positions of bind group 0 (wgsl/accel/geometry_bindings.wgsl) as storage
// buffers of 32-bit words: any size.

@group(0) @binding(0) var<storage, read> bvh_nodes: array<u32>;       // NODE_WORDS per node
@group(0) @binding(1) var<storage, read> tri_positions: array<f32>;   // TRIANGLE_WORDS per triangle

fn bvh_word(i: u32) -> u32 {
    return bvh_nodes[i];
}

fn position_word(i: u32) -> f32 {
    return tri_positions[i];
}

// Row r (words 4r..4r+3), for the per-invocation fetches of accel/traversal_lanes.wgsl.
fn bvh_row(r: u32) -> vec4u {
    return vec4u(bvh_word(4u * r), bvh_word(4u * r + 1u), bvh_word(4u * r + 2u), bvh_word(4u * r + 3u));
}

fn position_row(r: u32) -> vec4f {
    return vec4f(position_word(4u * r), position_word(4u * r + 1u), position_word(4u * r + 2u), position_word(4u * r + 3u));
}

// The root's skip: the index past the whole tree.
fn bvh_node_count() -> u32 {
    return bvh_word(3u);
}

// How many direction-ordered copies of the nodes the buffer holds: 8, or 1 for a scene whose 8 copies
// would not fit one storage binding (wgpu_rt.scene.geometry.GeometryBuffers.orderings).
fn bvh_orderings() -> u32 {
    return arrayLength(&bvh_nodes) / (8u * bvh_node_count());   // 8 words a node (NODE_WORDS)
}
