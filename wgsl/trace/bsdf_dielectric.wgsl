// Dielectric interface (glass of index `ior` inside, 1 outside; the local z axis is the outward
// normal, so wi.z < 0 means the path is inside). Smooth: reflect with probability F, else refract
// (Fresnel-weighted choice, so the weight is 1 or the radiance scale 1/eta²). Rough: Walter et al.'s
// GGX microfacet BSDF with the visible normals of the incident side sampled, as Mitsuba's
// roughdielectric (weight G1(wo), times 1/eta² for transmission). Transmission either way is tinted by
// the material's transmittance (Mitsuba's specular_transmittance). A thin dielectric (a pane of no thickness,
// Mitsuba's thindielectric; shaded two-sided, wi.z > 0) reflects or lets light straight through, by the
// reflectance of its two faces summed over the bounces between them (thin_dielectric_reflectance).

// #import trace/material.wgsl
// #import trace/microfacet.wgsl

struct Fresnel {
    reflectance: f32,
    cos_t: f32,    // cosine of the refracted direction, signed opposite to cos_i
    eta_ti: f32,   // relative index eta_transmitted / eta_incident for this side
}

fn fresnel_dielectric(cos_i: f32, ior: f32) -> Fresnel {
    let eta_ti = select(1.0 / ior, ior, cos_i >= 0.0);
    let inv = 1.0 / eta_ti;
    let cos_t2 = 1.0 - (1.0 - cos_i * cos_i) * inv * inv;
    if cos_t2 <= 0.0 {
        return Fresnel(1.0, 0.0, eta_ti);
    }
    let ci = abs(cos_i);
    let ct = sqrt(cos_t2);
    let a_s = (ci - eta_ti * ct) / (ci + eta_ti * ct);
    let a_p = (eta_ti * ci - ct) / (eta_ti * ci + ct);
    let cos_t = select(ct, -ct, cos_i >= 0.0);
    return Fresnel(0.5 * (a_s * a_s + a_p * a_p), cos_t, eta_ti);
}

// The tint of light crossing the surface (wgpu_rt.trace.scene_data packs it in the record's eta).
fn dielectric_transmittance(m: Material) -> vec3f {
    return m.eta;
}

fn refract_about(wi: vec3f, m: vec3f, fr: Fresnel) -> vec3f {
    let inv = 1.0 / fr.eta_ti;
    return m * (dot(wi, m) * inv + fr.cos_t) - wi * inv;
}

fn dielectric_eval(m: Material, wi: vec3f, wo: vec3f) -> BsdfEval {
    let cos_i = wi.z;
    let cos_o = wo.z;
    if m.roughness < DELTA_ROUGHNESS || cos_i == 0.0 || cos_o == 0.0 {
        return BsdfEval(vec3f(0.0), 0.0);
    }
    let alpha = m.roughness;
    let is_reflection = cos_i * cos_o > 0.0;
    let eta = select(1.0 / m.ior, m.ior, cos_i > 0.0);
    var h = normalize(wi + wo * select(eta, 1.0, is_reflection));
    h = h * sign(h.z);
    let dot_wi_h = dot(wi, h);
    let dot_wo_h = dot(wo, h);
    if dot_wi_h * cos_i <= 0.0 || dot_wo_h * cos_o <= 0.0 {
        return BsdfEval(vec3f(0.0), 0.0);
    }
    let d = ggx_d(h, alpha);
    let f = fresnel_dielectric(dot_wi_h, m.ior).reflectance;
    let g = ggx_g1(wi, h, alpha) * ggx_g1(wo, h, alpha);
    let pdf_h = ggx_visible_pdf(wi * sign(cos_i), h, alpha);
    if is_reflection {
        let value = f * d * g / (4.0 * abs(cos_i));
        return BsdfEval(vec3f(value), f * pdf_h / (4.0 * abs(dot_wo_h)));
    }
    let denom = dot_wi_h + eta * dot_wo_h;
    let value = abs((1.0 - f) * d * g * dot_wi_h * dot_wo_h / (cos_i * denom * denom));
    let pdf = (1.0 - f) * pdf_h * eta * eta * abs(dot_wo_h) / (denom * denom);
    return BsdfEval(value * dielectric_transmittance(m), pdf);
}

fn dielectric_sample(m: Material, wi: vec3f, u_lobe: f32, u: vec2f) -> BsdfSample {
    if wi.z == 0.0 {
        return no_sample();
    }
    if m.roughness < DELTA_ROUGHNESS {
        let fr = fresnel_dielectric(wi.z, m.ior);
        if u_lobe < fr.reflectance {
            return BsdfSample(vec3f(-wi.x, -wi.y, wi.z), 0.0, vec3f(1.0), 1.0, true);
        }
        let wo = vec3f(-wi.x / fr.eta_ti, -wi.y / fr.eta_ti, fr.cos_t);
        return BsdfSample(wo, 0.0, dielectric_transmittance(m) / (fr.eta_ti * fr.eta_ti), fr.eta_ti, true);
    }
    let alpha = m.roughness;
    let side = sign(wi.z);
    let h = ggx_sample_visible(wi * side, alpha, u);
    let pdf_h = ggx_visible_pdf(wi * side, h, alpha);
    let dot_wi_h = dot(wi, h);
    let fr = fresnel_dielectric(dot_wi_h, m.ior);
    if u_lobe < fr.reflectance {
        let wo = 2.0 * dot_wi_h * h - wi;
        if wo.z * wi.z <= 0.0 {
            return no_sample();
        }
        let pdf = fr.reflectance * pdf_h / (4.0 * abs(dot(wo, h)));
        return BsdfSample(wo, pdf, vec3f(ggx_g1(wo, h, alpha)), 1.0, false);
    }
    let wo = refract_about(wi, h, fr);
    if wo.z * wi.z >= 0.0 {
        return no_sample();
    }
    let dot_wo_h = dot(wo, h);
    let denom = dot_wi_h + fr.eta_ti * dot_wo_h;
    let pdf = (1.0 - fr.reflectance) * pdf_h * fr.eta_ti * fr.eta_ti * abs(dot_wo_h) / (denom * denom);
    let weight = ggx_g1(wo, h, alpha) / (fr.eta_ti * fr.eta_ti);
    return BsdfSample(wo, pdf, weight * dielectric_transmittance(m), fr.eta_ti, false);
}

// The reflectance of a pane of index `ior` at incidence cosine `cos_i`: its faces' R plus what bounces between
// them and leaves on the side it came from, R + (1 − R)² R / (1 − R²) = 2R / (1 + R) (1 where R is).
fn thin_dielectric_reflectance(cos_i: f32, ior: f32) -> f32 {
    let r = fresnel_dielectric(abs(cos_i), ior).reflectance;
    return 2.0 * r / (1.0 + r);
}

fn thin_dielectric_sample(m: Material, wi: vec3f, u_lobe: f32) -> BsdfSample {
    if u_lobe < thin_dielectric_reflectance(wi.z, m.ior) {
        return BsdfSample(vec3f(-wi.x, -wi.y, wi.z), 0.0, vec3f(1.0), 1.0, true);
    }
    return BsdfSample(-wi, 0.0, dielectric_transmittance(m), 1.0, true);
}
