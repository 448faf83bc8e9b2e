// The walk of a single-level scene's tree, or of a two-level scene's bottom levels, in the threaded binary
// layout (wgpu_rt.accel.bvh.ordered_threaded_nodes), imported by accel/bvh.wgsl; geometry laid out wide
// swaps in accel/walk_wide.wgsl.

// #import accel/walk_tree.wgsl

// Walks the node copy of the ray's octant.
fn walk_scene(state: ptr<function, WalkState>, ray: TraversalRay, shadow_ray: TraversalRay, shadow_length: f32,
              dir: vec3f) {
    let node_count = bvh_node_count();
    walk_tree(state, ray, shadow_ray, shadow_length, octant_copy_start(dir, node_count), node_count, NO_INSTANCE);
}

// An instance's bottom level (accel/bvh.wgsl, trace_ray_pair): the node copy of the object-space
// direction's octant.
fn walk_bottom_level(state: ptr<function, WalkState>, ray: TraversalRay, shadow_ray: TraversalRay,
                     shadow_length: f32, entry: InstanceEntry, object_dir: vec3f, instance: u32) {
    walk_tree(state, ray, shadow_ray, shadow_length,
              entry.first_node + entry.node_count * (packet_octant(object_dir) % entry.orderings),
              entry.node_count, instance);
}
