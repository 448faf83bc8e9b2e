// The walk of a tree in the 4-wide layout (wgpu_rt.accel.bvh.wide_nodes), swapped in for
// accel/walk_threaded.wgsl (layout "wide"): a single-level scene's tree (walk_scene), or each bottom level
// of a two-level one (walk_bottom_level; its top level stays threaded). A node's fetch (fetch_wide:
// accel/wide_node_full.wgsl, or with layout "wide8" accel/wide_node_quantized.wgsl, its boxes stored
// in 8 bits a coordinate) gives the boxes of its four children, tested for both rays as
// vec4 rows; the children entered are taken nearest first (by the nearer of the two rays' entry
// distances): the nearest next, the others pushed farthest first. With accel/traversal_lanes.wgsl each
// invocation walks alone, ordered by its own distances; with accel/traversal_subgroup.wgsl the subgroup
// walks as one packet (a child is entered when any ray enters it, ordered by the packet's nearest entry,
// node and triangle fetched once for all its lanes), so the stack, the same in every lane, never
// diverges.

// #import accel/walk_tree.wgsl
// #import accel/wide_node_full.wgsl

const WIDE_LEAF: u32 = 0x80000000u;              // wgpu_rt.accel.bvh.WIDE_LEAF
const WIDE_EMPTY: u32 = 0xffffffffu;             // wgpu_rt.accel.bvh.WIDE_EMPTY
const WIDE_STACK_SIZE: u32 = 96u;                // == wgpu_rt.accel.bvh.WIDE_STACK_SIZE
const WIDE_MISS: f32 = 3.0e38;                   // the entry distance of a child no ray enters

// Where `ray` enters each of the four boxes within (0, t_max), WIDE_MISS where it does not: box_hit's
// slab test (accel/walk_tree.wgsl) four boxes at a time.
fn wide_entries(lo_x: vec4f, lo_y: vec4f, lo_z: vec4f, hi_x: vec4f, hi_y: vec4f, hi_z: vec4f, ray: TraversalRay,
                t_max: f32) -> vec4f {
    let t0x = (lo_x - ray.origin.x) * ray.inv_dir.x;
    let t1x = (hi_x - ray.origin.x) * ray.inv_dir.x;
    let t0y = (lo_y - ray.origin.y) * ray.inv_dir.y;
    let t1y = (hi_y - ray.origin.y) * ray.inv_dir.y;
    let t0z = (lo_z - ray.origin.z) * ray.inv_dir.z;
    let t1z = (hi_z - ray.origin.z) * ray.inv_dir.z;
    let near = max(max(min(t0x, t1x), min(t0y, t1y)), max(min(t0z, t1z), vec4f(0.0)));
    let far = min(min(max(t0x, t1x), max(t0y, t1y)), min(max(t0z, t1z), vec4f(t_max))) * BVH_BOX_SLACK;
    return select(vec4f(WIDE_MISS), near, near <= far & near < vec4f(t_max));
}

// One step of a sorting network on the children's (key, reference, closest-hit entry) triples: slots i
// and j in ascending order of key.
fn order_pair(keys: ptr<function, vec4f>, refs: ptr<function, vec4u>, entries: ptr<function, vec4f>, i: u32, j: u32) {
    let swap = (*keys)[j] < (*keys)[i];
    let key_i = (*keys)[i];
    let ref_i = (*refs)[i];
    let entry_i = (*entries)[i];
    (*keys)[i] = select(key_i, (*keys)[j], swap);
    (*keys)[j] = select((*keys)[j], key_i, swap);
    (*refs)[i] = select(ref_i, (*refs)[j], swap);
    (*refs)[j] = select((*refs)[j], ref_i, swap);
    (*entries)[i] = select(entry_i, (*entries)[j], swap);
    (*entries)[j] = select((*entries)[j], entry_i, swap);
}

// Pushed children carry where the closest-hit ray enters them, so that one which a closer hit found
// since then has culled is dropped when it comes off the stack, unfetched, once the shadow ray (if any)
// is done with (for every ray of a packet): it could only matter to that ray.

// The walk's stack of (reference, bits of the closest-hit ray's entry), one per invocation rather than one
// per walk: a function's array is zeroed at every call, and a path walks once per ray query, a two-level
// scene once per instance entered (lavapipe, the bunny walked wide at 96²: static 12 %, moving 28 % less
// time a frame, §22).
var<private> wide_stack: array<vec2u, WIDE_STACK_SIZE>;

// The tree starts at node slot `base`; `instance` names it in hits.
fn walk_wide_tree(state: ptr<function, WalkState>, ray: TraversalRay, shadow_ray: TraversalRay, shadow_length: f32,
                  base: u32, instance: u32) {
    var depth = 0u;
    var next = 0u;   // the root, a wide node
    loop {
        (*state).loop_passes += 1u;
        if next >= WIDE_LEAF {
            let first = (next & ~WIDE_LEAF) >> LEAF_COUNT_BITS;
            test_triangles(state, ray, shadow_ray, shadow_length, first, first + (next & LEAF_COUNT_MASK),
                           instance);
            // Shadow-only queries (no closest-hit ray) are done at their first blockers.
            if packet_all((*state).occluded && !((*state).hit.t > 0.0)) { break; }
            next = WIDE_EMPTY;
        } else {
            let node = fetch_wide(base, next);
            var refs = node.children;
            var entries = wide_entries(node.lo_x, node.lo_y, node.lo_z, node.hi_x, node.hi_y, node.hi_z, ray,
                                       (*state).hit.t);
            let shadow = select(wide_entries(node.lo_x, node.lo_y, node.lo_z, node.hi_x, node.hi_y, node.hi_z,
                                             shadow_ray, shadow_length), vec4f(WIDE_MISS), (*state).occluded);
            var keys = select(packet_min4(min(entries, shadow)), vec4f(WIDE_MISS), refs == vec4u(WIDE_EMPTY));
            order_pair(&keys, &refs, &entries, 0u, 1u);
            order_pair(&keys, &refs, &entries, 2u, 3u);
            order_pair(&keys, &refs, &entries, 0u, 2u);
            order_pair(&keys, &refs, &entries, 1u, 3u);
            order_pair(&keys, &refs, &entries, 1u, 2u);
            let entered = vec4u(keys < vec4f(WIDE_MISS));
            next = select(WIDE_EMPTY, refs.x, entered.x != 0u);
            // Farthest first, so the nearer ones come off the stack sooner; at most WIDTH - 1 per level.
            let bits = bitcast<vec4u>(entries);
            if entered.w != 0u { wide_stack[depth] = vec2u(refs.w, bits.w); }
            if entered.z != 0u { wide_stack[depth + entered.w] = vec2u(refs.z, bits.z); }
            if entered.y != 0u { wide_stack[depth + entered.w + entered.z] = vec2u(refs.y, bits.y); }
            depth += entered.y + entered.z + entered.w;
        }
        if next == WIDE_EMPTY {   // off the stack: the nearest pushed child that may still matter
            loop {
                (*state).loop_passes += 1u;
                if depth == 0u { break; }
                depth -= 1u;
                let pushed = wide_stack[depth];
                if !packet_all((*state).occluded && bitcast<f32>(pushed.y) >= (*state).hit.t) {
                    next = pushed.x;
                    break;
                }
            }
            if next == WIDE_EMPTY { break; }
        }
    }
}

fn walk_scene(state: ptr<function, WalkState>, ray: TraversalRay, shadow_ray: TraversalRay, shadow_length: f32,
              dir: vec3f) {
    walk_wide_tree(state, ray, shadow_ray, shadow_length, 0u, NO_INSTANCE);
}

// An instance's bottom level (accel/bvh.wgsl, trace_ray_pair): one wide tree at the entry's first node
// (no direction-ordered copies: the walk orders the children by distance).
fn walk_bottom_level(state: ptr<function, WalkState>, ray: TraversalRay, shadow_ray: TraversalRay,
                     shadow_length: f32, entry: InstanceEntry, object_dir: vec3f, instance: u32) {
    walk_wide_tree(state, ray, shadow_ray, shadow_length, entry.first_node, instance);
}
