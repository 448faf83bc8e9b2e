// Glass without absorption: what trace/trace.wgsl multiplies a path's throughput by for a segment it travelled
// inside glass, for kernels of scenes whose glass absorbs nothing (1, folded away). A scene with an absorbing
// dielectric swaps in trace/interior_absorbing.wgsl (wgpu_rt/trace/trace_pass.py).

// #import trace/material.wgsl

// Of the segment of `distance` that ended at a surface of material `m` whose front faced away by `cos_front`.
fn interior_transmittance(m: Material, cos_front: f32, distance: f32) -> vec3f {
    return vec3f(1.0);
}
