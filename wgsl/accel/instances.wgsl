// A two-level scene (wgpu_rt.accel.geometry.InstancedGeometry): bvh_nodes starts with the top level,
// a tree over the instances' world boxes whose leaves name an instance, then the instances' entries
// (how the walk moves into one: accel/bvh.wgsl, instance_entry) and each bottom level (triangles in
// its own space). The records here carry what a hit needs to come back to world space.

// #import accel/geometry_bindings.wgsl

const HAS_INSTANCES: bool = true;

@group(0) @binding(4) var<storage, read> instances: array<Instance>;

fn instance_record(instance: u32) -> Instance {
    return instances[instance];
}
