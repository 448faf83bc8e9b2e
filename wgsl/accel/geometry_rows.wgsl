// The BVH nodes and triangle positions of bind group 0 (wgsl/accel/geometry_bindings.wgsl) as storage
// buffers of 16-byte rows, so that each row an invocation fetches for itself (accel/traversal_lanes.wgsl:
// a node's two rows or seven, a vertex's one) is a single vector load. Swapped for
// accel/geometry_words.wgsl where wgpu_rt.trace.bvh_choice measured it faster (variants "+rows").

@group(0) @binding(0) var<storage, read> bvh_nodes: array<vec4u>;       // NODE_WORDS / 4 rows per node
@group(0) @binding(1) var<storage, read> tri_positions: array<vec4f>;   // TRIANGLE_WORDS / 4 rows per triangle

fn bvh_row(r: u32) -> vec4u {
    return bvh_nodes[r];
}

fn position_row(r: u32) -> vec4f {
    return tri_positions[r];
}

fn bvh_word(i: u32) -> u32 {
    return bvh_nodes[i >> 2u][i & 3u];
}

fn position_word(i: u32) -> f32 {
    return tri_positions[i >> 2u][i & 3u];
}

// The root's skip: the index past the whole tree.
fn bvh_node_count() -> u32 {
    return bvh_word(3u);
}

// How many direction-ordered copies of the nodes the buffer holds (see accel/geometry_words.wgsl).
fn bvh_orderings() -> u32 {
    return arrayLength(&bvh_nodes) / (2u * bvh_node_count());   // 2 rows a node (NODE_WORDS / 4)
}
