// Lambertian reflection, sampled by the cosine-weighted hemisphere (so the weight is the albedo).

// #import trace/material.wgsl
// #import trace/sampling.wgsl

fn diffuse_eval(m: Material, wi: vec3f, wo: vec3f) -> BsdfEval {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return BsdfEval(vec3f(0.0), 0.0);
    }
    return BsdfEval(m.reflectance * (INV_PI * wo.z), wo.z * INV_PI);
}

fn diffuse_sample(m: Material, wi: vec3f, u: vec2f) -> BsdfSample {
    if wi.z <= 0.0 {
        return no_sample();
    }
    let wo = square_to_cosine_hemisphere(u);
    return BsdfSample(wo, wo.z * INV_PI, m.reflectance, 1.0, false);
}
