// The albedo the denoiser sees: its guide plane, and the factor that turns a pixel's colour into the
// irradiance it denoises (frame/pack.wgsl divides by albedo + 0.01, frame/unpack.wgsl multiplies back).
// That quotient is smooth only where the factor is what the colour is a multiple of, so besides a
// surface's reflectance the albedo counts what a pixel shows without reflecting anything: a front-facing
// emitter's emission (reflectance + emission, at most 1) and, where the path escapes, the background's
// radiance (at most 1). With those at 0, a pixel half sky and half floor read as the floor's irradiance
// times two plus the sky's times 100, and the denoiser, pulled towards the floor, left a dark seam along
// every horizon and emitter's rim (BENCHMARKS.md §28).

// #import trace/trace_bindings.wgsl
// #import trace/bsdf.wgsl

// A non-delta surface hit from the side `front` (the side an emitter's winding faces) says.
fn surface_albedo(m: Material, front: bool) -> vec3f {
    var albedo = m.reflectance;
    if HAS_CONDUCTOR && m.kind == MATERIAL_CONDUCTOR {
        albedo = m.reflectance * fresnel_conductor(1.0, m.eta, m.k);
    }
    if HAS_DIELECTRIC && m.kind == MATERIAL_DIELECTRIC {
        albedo = vec3f(1.0);
    }
    if HAS_AREA_LIGHTS && m.is_emissive != 0u && front {
        albedo = min(albedo + m.emission, vec3f(1.0));
    }
    return albedo;
}

// A path that escapes the scene.
fn background_albedo() -> vec3f {
    return clamp(params.background, vec3f(0.0), vec3f(1.0));
}
