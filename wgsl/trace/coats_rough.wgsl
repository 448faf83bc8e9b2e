// Whether a plastic's coat is rough (GGX, trace/bsdf_plastic.wgsl): at a roughness of DELTA_ROUGHNESS or more.
// Swapped in for trace/coats_smooth.wgsl where a scene has a rough coat (wgpu_rt/trace/trace_pass.py).

// #import trace/material.wgsl

fn plastic_is_rough(m: Material) -> bool {
    return m.roughness >= DELTA_ROUGHNESS;
}
