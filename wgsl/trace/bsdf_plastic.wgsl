// Plastic, as Mitsuba's `plastic` (roughness below DELTA_ROUGHNESS) and `roughplastic` (GGX, above), both in
// their linear mode: a Lambertian base of `reflectance` under a dielectric coat of index `ior` over 1.
// Light meets the coat: some is reflected by it, the share t(θi) enters, is scattered diffusely, and leaves
// through the coat; the diffuse lobe is ρ / (1 − Fint) · t(θi) t(θo) / ior² · cos θo / π, Fint being the
// coat's mean internal reflectance. A smooth coat reflects as a mirror (a delta lobe) with t = 1 − F and
// Fint = fresnel_diffuse_reflectance; a rough one reflects as a GGX microfacet lobe F·D·G / (4 cos θi), and
// its t and Fint (what passes the coat unshadowed; wgpu_rt/trace/coat.py) come from the record's conductor
// words. Samples pick the coat with probability (1 − t(θi))·w / ((1 − t(θi))·w + t(θi)(1 − w)), w the coat's
// weight against the base's (their reflectances' means, 1 and mean(ρ), as Mitsuba weighs them), else the
// cosine-weighted base. Both faces behave alike (the shading normal is turned toward the incoming path, as
// for diffuse).

// #import trace/material.wgsl
// #import trace/sampling.wgsl
// #import trace/microfacet.wgsl
// #import trace/bsdf_dielectric.wgsl
// #import trace/coats_smooth.wgsl

const COAT_KNOTS: u32 = 11u;    // wgpu_rt/trace/coat.py: t at cos θ = (i / 10)²; the twelfth half is Fint

// The mean reflectance of a dielectric boundary of relative index `eta` for diffuse light (the fits
// Mitsuba's fresnel_diffuse_reflectance uses: Egan and Hilgeman below 1, d'Eon and Irving above).
fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    let inv = 1.0 / eta;
    if eta < 1.0 {
        return 0.0636 * inv + eta * (eta * -1.4399 + 0.7099) + 0.6681;
    }
    return 0.919317 + inv * (-3.4793 + inv * (6.75335 + inv * (-7.80989 + inv * (4.98554 + inv * -1.36881))));
}

// Half `i` (0 … 11) of a rough coat's table, packed two to a word in its eta and k.
// (components picked by selects: an array indexed at run time sits in memory on most drivers)
fn coat_half(m: Material, i: u32) -> f32 {
    let word = i >> 1u;
    let three = select(m.k, m.eta, word < 3u);
    let component = word % 3u;
    let halves = unpack2x16float(bitcast<u32>(select(select(three.z, three.y, component == 1u), three.x,
                                                     component == 0u)));
    return select(halves.x, halves.y, (i & 1u) == 1u);
}

// The share of light arriving at cos θ = `cos_theta` that passes the coat into the base.
fn coat_transmittance(m: Material, cos_theta: f32) -> f32 {
    if !plastic_is_rough(m) {
        return 1.0 - fresnel_dielectric(cos_theta, m.ior).reflectance;
    }
    let s = sqrt(clamp(cos_theta, 0.0, 1.0)) * f32(COAT_KNOTS - 1u);
    let i = min(u32(s), COAT_KNOTS - 2u);
    return mix(coat_half(m, i), coat_half(m, i + 1u), s - f32(i));
}

fn coat_internal_reflectance(m: Material) -> f32 {
    if plastic_is_rough(m) {
        return coat_half(m, COAT_KNOTS);
    }
    return fresnel_diffuse_reflectance(1.0 / m.ior);
}

fn plastic_specular_probability(m: Material, t_i: f32) -> f32 {
    let weight = 1.0 / (1.0 + (m.reflectance.x + m.reflectance.y + m.reflectance.z) / 3.0);
    let specular = (1.0 - t_i) * weight;
    let total = specular + t_i * (1.0 - weight);
    // both lobes empty (a black base under a coat of index 1): sample the (black) base
    return select(0.0, specular / total, total > 0.0);
}

// The diffuse lobe's f·cos θo (before the 1 / π and the cosine, which the callers apply).
fn plastic_diffuse(m: Material, t_i: f32, t_o: f32) -> vec3f {
    return m.reflectance / (1.0 - coat_internal_reflectance(m)) * (t_i * t_o / (m.ior * m.ior));
}

fn plastic_eval(m: Material, wi: vec3f, wo: vec3f) -> BsdfEval {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return BsdfEval(vec3f(0.0), 0.0);
    }
    let t_i = coat_transmittance(m, wi.z);
    let specular = plastic_specular_probability(m, t_i);
    var value = plastic_diffuse(m, t_i, coat_transmittance(m, wo.z)) * (INV_PI * wo.z);
    var pdf = (1.0 - specular) * wo.z * INV_PI;
    if plastic_is_rough(m) {
        let h = normalize(wi + wo);
        let alpha = m.roughness;
        let d = ggx_d(h, alpha);
        let g1_wi = ggx_g1(wi, h, alpha);
        let f = fresnel_dielectric(dot(wi, h), m.ior).reflectance;
        value += vec3f(f * d * g1_wi * ggx_g1(wo, h, alpha) / (4.0 * wi.z));
        pdf += specular * g1_wi * d / (4.0 * wi.z);
    }
    return BsdfEval(value, pdf);
}

fn plastic_sample(m: Material, wi: vec3f, u_lobe: f32, u: vec2f) -> BsdfSample {
    if wi.z <= 0.0 {
        return no_sample();
    }
    let t_i = coat_transmittance(m, wi.z);
    let specular = plastic_specular_probability(m, t_i);
    if !plastic_is_rough(m) {
        if u_lobe < specular {
            return BsdfSample(vec3f(-wi.x, -wi.y, wi.z), 0.0, vec3f((1.0 - t_i) / specular), 1.0, true);
        }
        let wo = square_to_cosine_hemisphere(u);
        let diffuse_probability = 1.0 - specular;
        return BsdfSample(wo, diffuse_probability * wo.z * INV_PI,
                          plastic_diffuse(m, t_i, coat_transmittance(m, wo.z)) / diffuse_probability, 1.0, false);
    }
    // rough: either lobe's direction, weighed by both lobes' sum over both lobes' pdfs (as Mitsuba does)
    var wo = square_to_cosine_hemisphere(u);
    if u_lobe < specular {
        let h = ggx_sample_visible(wi, m.roughness, u);
        wo = 2.0 * dot(wi, h) * h - wi;
    }
    let both = plastic_eval(m, wi, wo);
    if both.pdf <= 0.0 {
        return no_sample();
    }
    return BsdfSample(wo, both.pdf, both.value / both.pdf, 1.0, false);
}
