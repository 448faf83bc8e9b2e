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

// A node's and a vertex's records are whole rows of the geometry words module (bvh_row, position_row):
// single vector loads where accel/geometry_rows.wgsl provides them.
fn bvh_node(index: u32) -> BvhNode {
    let head = bvh_row(2u * index);        // NODE_WORDS = 2 rows
    let tail = bvh_row(2u * index + 1u);
    return BvhNode(bitcast<vec3f>(head.xyz), head.w, bitcast<vec3f>(tail.xyz), tail.w);
}

// Wide node `index` of the tree that starts at node slot `base` (8-word slots: a two-level scene's bottom
// level follows the top level's threaded nodes).
fn wide_node(base: u32, index: u32) -> WideNode {
    let at = (NODE_WORDS / 4u) * base + (WIDE_NODE_WORDS / 4u) * index;
    return WideNode(bitcast<vec4f>(bvh_row(at)), bitcast<vec4f>(bvh_row(at + 1u)), bitcast<vec4f>(bvh_row(at + 2u)),
                    bitcast<vec4f>(bvh_row(at + 3u)), bitcast<vec4f>(bvh_row(at + 4u)),
                    bitcast<vec4f>(bvh_row(at + 5u)), bvh_row(at + 6u));
}

fn bvh_triangle(prim: u32) -> TrianglePositions {
    let at = (TRIANGLE_WORDS / 4u) * prim;   // one row (x, y, z, unused) a vertex
    return TrianglePositions(position_row(at).xyz, position_row(at + 1u).xyz, position_row(at + 2u).xyz);
}
