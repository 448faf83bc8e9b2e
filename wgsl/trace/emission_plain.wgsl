// Emission without textures: what trace/emitters.wgsl and trace/trace.wgsl multiply an emitter's radiance by, for
// kernels of scenes whose lights have no emission texture (white, folded away). A scene with one swaps in
// trace/emission_textures.wgsl (wgpu_rt/trace/trace_pass.py): reading the emitter's two words for it on every
// light sample cost cornell and sun-room 37–43 % of their trace time on lavapipe (BENCHMARKS.md §49).

// Emission texture `image` at barycentrics (u, v) of placed triangle `prim`.
fn emission_color(image: u32, prim: u32, u: f32, v: f32) -> vec3f {
    return vec3f(1.0);
}

// The emission texture's colour where a path meets emissive placed triangle `prim` at (u, v).
fn triangle_emission_color(prim: u32, u: f32, v: f32) -> vec3f {
    return vec3f(1.0);
}
