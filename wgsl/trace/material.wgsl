// The material record shared by the BSDF modules: one struct for every kind (diffuse, conductor,
// dielectric, plastic), as packed by wgpu_rt.trace.scene_data. Roughness is the GGX alpha; below
// DELTA_ROUGHNESS a lobe is treated as perfectly specular (a Dirac delta).

// #import trace/features.wgsl

const MATERIAL_DIFFUSE: u32 = 0u;
const MATERIAL_CONDUCTOR: u32 = 1u;
const MATERIAL_DIELECTRIC: u32 = 2u;
const MATERIAL_PLASTIC: u32 = 3u;      // compiled with the glass (HAS_DIELECTRIC): its coat is one
const MATERIAL_THIN_DIELECTRIC: u32 = 4u;   // a pane of no thickness (HAS_DIELECTRIC too), always smooth
const DELTA_ROUGHNESS: f32 = 1e-4;

struct Material {
    reflectance: vec3f,
    kind: u32,
    emission: vec3f,
    roughness: f32,
    eta: vec3f,     // conductor: real part of the complex index of refraction; rough plastic: its coat's table;
                    // dielectric, thin or not: the tint of light crossing it (dielectric_transmittance)
    ior: f32,       // dielectric: interior index over an exterior of 1
    k: vec3f,       // conductor: imaginary part; rough plastic: the rest of the table (trace/bsdf_plastic.wgsl)
    is_emissive: u32,
}

// What a BSDF sample returns: the direction (local frame), weight = f·|cos|/pdf, the solid-angle pdf
// (0 for a delta lobe), and the relative index of refraction crossed (1 for reflection).
struct BsdfSample {
    wo: vec3f,
    pdf: f32,
    weight: vec3f,
    eta: f32,
    is_delta: bool,
}

// f·|cos θo| and the pdf with which bsdf sampling would have produced wo.
struct BsdfEval {
    value: vec3f,
    pdf: f32,
}

fn material_is_delta(m: Material) -> bool {
    // without glass or metal in the kernel, nothing is delta (and kind/roughness are never fetched)
    // (a plastic has a diffuse lobe under its coat: never delta as a whole)
    return (HAS_CONDUCTOR || HAS_DIELECTRIC) && m.kind != MATERIAL_DIFFUSE && m.kind != MATERIAL_PLASTIC
           && m.roughness < DELTA_ROUGHNESS;
}

fn no_sample() -> BsdfSample {
    return BsdfSample(vec3f(0.0, 0.0, 1.0), 0.0, vec3f(0.0), 1.0, false);
}
