// No thin panes: every surface a shadow ray meets stops it (accel/walk_tree.wgsl's test_triangles), for kernels of
// scenes without a thin_dielectric and for the ray-query kernels. A path-tracing kernel of a scene with one swaps in
// trace/shadow_panes.wgsl (wgpu_rt/trace/trace_pass.py).

// #import accel/geometry_bindings.wgsl

const SHADOWS_CROSS_PANES: bool = false;

// What a shadow ray keeps of its light crossing stored triangle `stored` (of `instance`; positions `p`) along
// direction `dir` (in the triangle's space): nothing.
fn pane_transmittance(stored: u32, instance: u32, p: TrianglePositions, dir: vec3f) -> vec3f {
    return vec3f(0.0);
}
