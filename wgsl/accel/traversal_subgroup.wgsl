// Traversal records fetched cooperatively: the invocations of a subgroup walk the BVH together as one
// packet. Each node or triangle is read once for the whole subgroup: lane k reads word k of the record
// and subgroupBroadcast hands every word to every lane. A subtree is entered when any lane's ray
// enters its box (packet_any), so each ray still sees every leaf its own walk would visit.
//
// Why: a CPU Vulkan driver (Mesa's lavapipe) runs a subgroup as one SIMD vector. There a read at
// divergent addresses costs a scalar loop over the lanes per 32-bit word, and both sides of every
// branch execute under a mask, so a packet that fetches each record once beats per-lane walks.
// Preconditions, checked by wgpu_rt.scene.geometry.traversal_module: subgroups of at least 8 lanes,
// lane = local_invocation_index mod subgroup size, and every invocation of a subgroup calls the
// traversal together (callers keep finished invocations in their loops instead of returning).

// #import accel/geometry_bindings.wgsl

var<private> traversal_lane: u32;

fn begin_traversal(local_index: u32) {
    traversal_lane = local_index & 7u;
}

fn packet_any(x: bool) -> bool {
    return subgroupAny(x);
}

fn packet_all(x: bool) -> bool {
    return subgroupAll(x);
}

// The wide walk's child order, the same for the whole packet: by the nearest entry of any of its rays.
fn packet_min4(x: vec4f) -> vec4f {
    return subgroupMin(x);
}

// The octant of the packet's summed direction (bit k: component k negative): the whole subgroup walks
// one node order, the one that suits its rays on average.
fn packet_octant(dir: vec3f) -> u32 {
    return direction_octant(subgroupAdd(dir));
}

fn bvh_node(index: u32) -> BvhNode {
    let word = bvh_word(NODE_WORDS * index + traversal_lane);
    return BvhNode(
        bitcast<vec3f>(vec3u(subgroupBroadcast(word, 0u), subgroupBroadcast(word, 1u), subgroupBroadcast(word, 2u))),
        subgroupBroadcast(word, 3u),
        bitcast<vec3f>(vec3u(subgroupBroadcast(word, 4u), subgroupBroadcast(word, 5u), subgroupBroadcast(word, 6u))),
        subgroupBroadcast(word, 7u));
}

// Words 0..3 and 4..7 of the lanes' eight: the first and second half of a row of 8 fetched words.
fn low_half(part: u32) -> vec4u {
    return vec4u(subgroupBroadcast(part, 0u), subgroupBroadcast(part, 1u), subgroupBroadcast(part, 2u),
                 subgroupBroadcast(part, 3u));
}

fn high_half(part: u32) -> vec4u {
    return vec4u(subgroupBroadcast(part, 4u), subgroupBroadcast(part, 5u), subgroupBroadcast(part, 6u),
                 subgroupBroadcast(part, 7u));
}

// Lane k fetches words k, 8 + k, 16 + k and 24 + k of the node (lanes 4..7 the node's last word again
// for the fourth, past its 28), and the rows come out of the broadcasts.
// Wide node `index` of the tree that starts at node slot `base` (as accel/traversal_lanes.wgsl's).
fn wide_node(base: u32, index: u32) -> WideNode {
    let first = NODE_WORDS * base + WIDE_NODE_WORDS * index;
    let at = first + traversal_lane;
    let words = vec4u(bvh_word(at), bvh_word(at + 8u), bvh_word(at + 16u), bvh_word(min(at + 24u, first + 27u)));
    return WideNode(bitcast<vec4f>(low_half(words.x)), bitcast<vec4f>(high_half(words.x)),
                    bitcast<vec4f>(low_half(words.y)), bitcast<vec4f>(high_half(words.y)),
                    bitcast<vec4f>(low_half(words.z)), bitcast<vec4f>(high_half(words.z)), low_half(words.w));
}

fn bvh_triangle(prim: u32) -> TrianglePositions {
    let at = TRIANGLE_WORDS * prim;
    let head = position_word(at + traversal_lane);          // words 0..7: vertex a, vertex b
    let tail = position_word(at + 8u + (traversal_lane & 3u));   // words 8..11: vertex c
    return TrianglePositions(
        vec3f(subgroupBroadcast(head, 0u), subgroupBroadcast(head, 1u), subgroupBroadcast(head, 2u)),
        vec3f(subgroupBroadcast(head, 4u), subgroupBroadcast(head, 5u), subgroupBroadcast(head, 6u)),
        vec3f(subgroupBroadcast(tail, 0u), subgroupBroadcast(tail, 1u), subgroupBroadcast(tail, 2u)));
}
