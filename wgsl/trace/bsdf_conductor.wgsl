// Conductor: Fresnel reflectance of a complex index of refraction eta + i·k (exact unpolarized
// formula), tinted by the material's reflectance; a perfect mirror below DELTA_ROUGHNESS, otherwise a
// GGX microfacet BRDF sampled through its visible normals (weight F·G1(wo), as Mitsuba's
// roughconductor).

// #import trace/material.wgsl
// #import trace/microfacet.wgsl

fn fresnel_conductor(cos_i: f32, eta: vec3f, k: vec3f) -> vec3f {
    let c2 = cos_i * cos_i;
    let s2 = 1.0 - c2;
    let s4 = s2 * s2;
    let t1 = eta * eta - k * k - vec3f(s2);
    let a2pb2 = sqrt(max(vec3f(0.0), t1 * t1 + 4.0 * k * k * eta * eta));
    let a = sqrt(max(vec3f(0.0), 0.5 * (a2pb2 + t1)));
    let term1 = a2pb2 + vec3f(c2);
    let term2 = 2.0 * cos_i * a;
    let rs = (term1 - term2) / (term1 + term2);
    let term3 = a2pb2 * c2 + vec3f(s4);
    let term4 = term2 * s2;
    let rp = rs * (term3 - term4) / (term3 + term4);
    return 0.5 * (rs + rp);
}

fn conductor_eval(m: Material, wi: vec3f, wo: vec3f) -> BsdfEval {
    if m.roughness < DELTA_ROUGHNESS || wi.z <= 0.0 || wo.z <= 0.0 {
        return BsdfEval(vec3f(0.0), 0.0);
    }
    let h = normalize(wi + wo);
    let alpha = m.roughness;
    let d = ggx_d(h, alpha);
    let g1_wi = ggx_g1(wi, h, alpha);
    let g = g1_wi * ggx_g1(wo, h, alpha);
    let f = fresnel_conductor(dot(wi, h), m.eta, m.k) * m.reflectance;
    let value = f * (d * g / (4.0 * wi.z));
    let pdf = g1_wi * d / (4.0 * wi.z);
    return BsdfEval(value, pdf);
}

fn conductor_sample(m: Material, wi: vec3f, u: vec2f) -> BsdfSample {
    if wi.z <= 0.0 {
        return no_sample();
    }
    if m.roughness < DELTA_ROUGHNESS {
        let f = fresnel_conductor(wi.z, m.eta, m.k) * m.reflectance;
        return BsdfSample(vec3f(-wi.x, -wi.y, wi.z), 0.0, f, 1.0, true);
    }
    let alpha = m.roughness;
    let h = ggx_sample_visible(wi, alpha, u);
    let wo = 2.0 * dot(wi, h) * h - wi;
    if wo.z <= 0.0 {
        return no_sample();
    }
    let pdf = ggx_visible_pdf(wi, h, alpha) / (4.0 * dot(wo, h));
    let weight = fresnel_conductor(dot(wi, h), m.eta, m.k) * m.reflectance * ggx_g1(wo, h, alpha);
    return BsdfSample(wo, pdf, weight, 1.0, false);
}
