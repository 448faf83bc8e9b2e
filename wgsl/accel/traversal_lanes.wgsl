// Traversal records fetched by each invocation for itself: every invocation walks the BVH on its own
// (packet_any is the identity). The portable choice, and the right one where divergent memory reads
// are cheap (GPUs); accel/traversal_subgroup.wgsl replaces this module on CPU drivers.

// #import accel/geometry_bindings.wgsl

fn begin_traversal(local_index: u32) {}

fn packet_any(x: bool) -> bool {
    return x;
}

fn packet_all(x: bool) -> bool {
    return x;
}

// The wide walk's child order: by this invocation's own entry distances.
fn packet_min4(x: vec4f) -> vec4f {
    return x;
}

// The octant of the ray's direction (bit k: component k negative), which picks the walk's node order.
fn packet_octant(dir: vec3f) -> u32 {
    return direction_octant(dir);
}

fn bvh_node(index: u32) -> BvhNode {
    let at = NODE_WORDS * index;
    return BvhNode(bitcast<vec3f>(vec3u(bvh_word(at), bvh_word(at + 1u), bvh_word(at + 2u))), bvh_word(at + 3u),
                   bitcast<vec3f>(vec3u(bvh_word(at + 4u), bvh_word(at + 5u), bvh_word(at + 6u))),
                   bvh_word(at + 7u));
}

fn wide_row(at: u32) -> vec4u {
    return vec4u(bvh_word(at), bvh_word(at + 1u), bvh_word(at + 2u), bvh_word(at + 3u));
}

fn wide_node(index: u32) -> WideNode {
    let at = WIDE_NODE_WORDS * index;
    return WideNode(bitcast<vec4f>(wide_row(at)), bitcast<vec4f>(wide_row(at + 4u)), bitcast<vec4f>(wide_row(at + 8u)),
                    bitcast<vec4f>(wide_row(at + 12u)), bitcast<vec4f>(wide_row(at + 16u)),
                    bitcast<vec4f>(wide_row(at + 20u)), wide_row(at + 24u));
}

fn bvh_triangle(prim: u32) -> TrianglePositions {
    return TrianglePositions(triangle_vertex(prim, 0u), triangle_vertex(prim, 1u), triangle_vertex(prim, 2u));
}
