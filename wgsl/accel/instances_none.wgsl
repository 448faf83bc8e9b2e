// A single-level scene (wgpu_rt.accel.geometry.GeometryBuffers): world-space triangles, no instances.
// accel/bvh.wgsl imports this module; wgpu_rt.accel.geometry swaps in accel/instances.wgsl for a
// two-level scene. With HAS_INSTANCES false the instance code in accel/bvh.wgsl is constant-folded
// away, so a static scene's walk is the single-level one.

// #import accel/geometry_bindings.wgsl

const HAS_INSTANCES: bool = false;

fn instance_record(instance: u32) -> Instance {
    return Instance(mat4x3f(), mat3x3f(), 0u, 0u, FROM_TRIANGLE, FROM_TRIANGLE);
}

fn remember_hit(prim: u32, instance: u32) {}

fn placed_instance(prim: u32) -> u32 {
    return 0u;
}
