// The BSDF dispatcher: routes evaluation and sampling by material kind. The glass (and plastic) and metal
// arms sit behind the HAS_DIELECTRIC / HAS_CONDUCTOR switches, so a specialized kernel contains only the
// models its scene uses.

// #import trace/features.wgsl
// #import trace/bsdf_diffuse.wgsl
// #import trace/bsdf_conductor.wgsl
// #import trace/bsdf_dielectric.wgsl
// #import trace/bsdf_plastic.wgsl

fn bsdf_eval(m: Material, wi: vec3f, wo: vec3f) -> BsdfEval {
    if HAS_CONDUCTOR && m.kind == MATERIAL_CONDUCTOR {
        return conductor_eval(m, wi, wo);
    }
    if HAS_DIELECTRIC && m.kind == MATERIAL_DIELECTRIC {
        return dielectric_eval(m, wi, wo);
    }
    if HAS_DIELECTRIC && m.kind == MATERIAL_PLASTIC {
        return plastic_eval(m, wi, wo);
    }
    if HAS_DIELECTRIC && m.kind == MATERIAL_THIN_DIELECTRIC {
        return BsdfEval(vec3f(0.0), 0.0);      // delta lobes only
    }
    return diffuse_eval(m, wi, wo);
}

fn bsdf_sample(m: Material, wi: vec3f, u_lobe: f32, u: vec2f) -> BsdfSample {
    if HAS_CONDUCTOR && m.kind == MATERIAL_CONDUCTOR {
        return conductor_sample(m, wi, u);
    }
    if HAS_DIELECTRIC && m.kind == MATERIAL_DIELECTRIC {
        return dielectric_sample(m, wi, u_lobe, u);
    }
    if HAS_DIELECTRIC && m.kind == MATERIAL_PLASTIC {
        return plastic_sample(m, wi, u_lobe, u);
    }
    if HAS_DIELECTRIC && m.kind == MATERIAL_THIN_DIELECTRIC {
        return thin_dielectric_sample(m, wi, u_lobe);
    }
    return diffuse_sample(m, wi, u);
}
