// Absorbing glass (Beer–Lambert): a segment that ends on the back face of a dielectric ran inside it, and keeps
// exp(−absorption · length) of its light per channel (the dielectric's absorption sits in its record's k words,
// wgpu_rt/trace/scene_data.py). This holds for closed glass meshes with nothing inside them: it is Mitsuba's
// homogeneous interior medium of sigma_t = absorption and albedo 0. Swapped in for trace/interior_clear.wgsl
// where a scene has an absorbing dielectric (wgpu_rt/trace/trace_pass.py).

// #import trace/material.wgsl

// Of the segment of `distance` that ended at a surface of material `m` whose front faced away by `cos_front`.
fn interior_transmittance(m: Material, cos_front: f32, distance: f32) -> vec3f {
    if m.kind == MATERIAL_DIELECTRIC && cos_front < 0.0 {
        return exp(-m.k * distance);
    }
    return vec3f(1.0);
}
