// Every triangle is whole: the walks' cutout test (accel/walk_tree.wgsl's test_triangles) for kernels of
// scenes without cut-out surfaces, and for the ray-query kernels, which have no textures. A path-tracing
// kernel of a scene with them swaps in trace/cutouts.wgsl (wgpu_rt/trace/trace_pass.py).

const HAS_CUTOUTS: bool = false;

// Whether stored triangle `stored` is cut away at barycentrics (u, v).
fn triangle_cut_away(stored: u32, u: f32, v: f32) -> bool {
    return false;
}
