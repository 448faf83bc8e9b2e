// Where a hit point was at the frame before, for a scene whose meshes bend (glTF skins and morph targets:
// wgpu_rt.accel.geometry.GeometryBuffers.previous_triangles): binding 3 of group 0 holds each triangle's three
// vertices at the frame before, in world space and in the BVH's order (xyz; w unused), so a point moves as its
// triangle's corners moved, whatever moved them. Swapped in for accel/motion_objects.wgsl; single level only.

// #import accel/geometry_bindings.wgsl

@group(0) @binding(3) var<storage, read> previous_vertices: array<vec4f>;

// The world position at the frame before of `position`, the point at barycentrics (u, v) of triangle `prim`.
fn previous_position(prim: u32, u: f32, v: f32, position: vec3f) -> vec3f {
    let at = 3u * prim;
    return (1.0 - u - v) * previous_vertices[at].xyz + u * previous_vertices[at + 1u].xyz
        + v * previous_vertices[at + 2u].xyz;
}
