// Whether a plastic's coat is rough, for kernels of scenes whose plastics are all smooth: never, so that
// trace/bsdf_plastic.wgsl's rough lobe and coat table fold away (compiled in, they cost smooth-plastic scenes
// 7–8 % of their trace time on lavapipe, BENCHMARKS.md §49). A scene with a rough coat swaps in
// trace/coats_rough.wgsl (wgpu_rt/trace/trace_pass.py).

// #import trace/material.wgsl

fn plastic_is_rough(m: Material) -> bool {
    return false;
}
