// Where a hit point was at the frame before, for motion vectors: binding 3 of group 0 holds one world-now →
// world-before matrix per object (wgpu_rt.accel.geometry.object_motion), which moves every point of a rigid
// object. accel/bvh.wgsl imports this module; a scene whose meshes bend swaps in accel/motion_vertices.wgsl.

// #import accel/geometry_bindings.wgsl
// #import accel/bvh.wgsl

@group(0) @binding(3) var<storage, read> object_motion: array<mat4x4f>;

// The world position at the frame before of `position`, the point at barycentrics (u, v) of triangle `prim`.
fn previous_position(prim: u32, u: f32, v: f32, position: vec3f) -> vec3f {
    return (object_motion[tri_object(prim)] * vec4f(position, 1.0)).xyz;
}
