// Smooth plastic, as Mitsuba's `plastic` (its linear mode): a Lambertian base of `reflectance` under a
// mirror-smooth dielectric coat of index `ior` over 1. Light meets the coat: a share F(θi) is reflected
// as by a mirror (a delta lobe), the rest enters, is scattered diffusely, and leaves through the coat;
// the diffuse lobe is ρ / (1 − Fdr) · (1 − F(θi)) (1 − F(θo)) / ior² · cos θo / π, Fdr being the
// coat's mean internal reflectance (fresnel_diffuse_reflectance). Samples pick the mirror with probability
// F(θi)·w / (F(θi)·w + (1 − F(θi))(1 − w)), w the specular lobe's weight against the diffuse one's
// (their reflectances' means, 1 and mean(ρ), as Mitsuba weighs them), else the cosine-weighted base.
// Both faces behave alike (the shading normal is turned toward the incoming path, as for diffuse).

// #import trace/material.wgsl
// #import trace/sampling.wgsl
// #import trace/bsdf_dielectric.wgsl

// The mean reflectance of a dielectric boundary of relative index `eta` for diffuse light (the fits
// Mitsuba's fresnel_diffuse_reflectance uses: Egan and Hilgeman below 1, d'Eon and Irving above).
fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    let inv = 1.0 / eta;
    if eta < 1.0 {
        return 0.0636 * inv + eta * (eta * -1.4399 + 0.7099) + 0.6681;
    }
    return 0.919317 + inv * (-3.4793 + inv * (6.75335 + inv * (-7.80989 + inv * (4.98554 + inv * -1.36881))));
}

fn plastic_specular_probability(m: Material, f_i: f32) -> f32 {
    let weight = 1.0 / (1.0 + (m.reflectance.x + m.reflectance.y + m.reflectance.z) / 3.0);
    let specular = f_i * weight;
    let total = specular + (1.0 - f_i) * (1.0 - weight);
    // both lobes empty (a black base under a coat of index 1): sample the (black) base
    return select(0.0, specular / total, total > 0.0);
}

// The diffuse lobe's f·cos θo (before the 1 / π and the cosine, which the callers apply).
fn plastic_diffuse(m: Material, f_i: f32, f_o: f32) -> vec3f {
    let fdr_int = fresnel_diffuse_reflectance(1.0 / m.ior);
    return m.reflectance / (1.0 - fdr_int) * ((1.0 - f_i) * (1.0 - f_o) / (m.ior * m.ior));
}

fn plastic_eval(m: Material, wi: vec3f, wo: vec3f) -> BsdfEval {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return BsdfEval(vec3f(0.0), 0.0);
    }
    let f_i = fresnel_dielectric(wi.z, m.ior).reflectance;
    let f_o = fresnel_dielectric(wo.z, m.ior).reflectance;
    let diffuse_probability = 1.0 - plastic_specular_probability(m, f_i);
    return BsdfEval(plastic_diffuse(m, f_i, f_o) * (INV_PI * wo.z), diffuse_probability * wo.z * INV_PI);
}

fn plastic_sample(m: Material, wi: vec3f, u_lobe: f32, u: vec2f) -> BsdfSample {
    if wi.z <= 0.0 {
        return no_sample();
    }
    let f_i = fresnel_dielectric(wi.z, m.ior).reflectance;
    let specular = plastic_specular_probability(m, f_i);
    if u_lobe < specular {
        return BsdfSample(vec3f(-wi.x, -wi.y, wi.z), 0.0, vec3f(f_i / specular), 1.0, true);
    }
    let wo = square_to_cosine_hemisphere(u);
    let f_o = fresnel_dielectric(wo.z, m.ior).reflectance;
    let diffuse_probability = 1.0 - specular;
    return BsdfSample(wo, diffuse_probability * wo.z * INV_PI, plastic_diffuse(m, f_i, f_o) / diffuse_probability,
                      1.0, false);
}
