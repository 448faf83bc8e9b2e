// The albedo the denoiser sees: its guide plane, and the factor that turns a pixel's colour into the
// irradiance it denoises (frame/pack.wgsl divides by albedo + 0.01, frame/unpack.wgsl multiplies back).
// That quotient is smooth only where the factor is what the colour is a multiple of. Where a path
// escapes, that is the background's radiance (at most 1): with 0 there, a pixel half sky and half floor
// read as the floor's irradiance times two plus the sky's times 100, and the denoiser, pulled towards the
// floor, left a dark seam along every horizon (BENCHMARKS.md §28). A black background stays at 0, so what
// the network leaks into it is multiplied by 0.01. An emitter keeps its reflectance, but at least
// EMITTER_ALBEDO_FLOOR grey: a lamp given emission and a black reflectance (as area lights often are)
// read as its radiance times 100 and came out dark inside a halo (+0.18 / +0.53 / +0.63 dB at 1 / 4 / 16
// spp on benchmarks/scenes/corridor-lamps.toml, +0.05 to +0.20 on sun-room's black sun; 0.8 gave less,
// BENCHMARKS.md §30). Adding its emission instead (at most 1) helped faint glowing objects but cost up to
// 0.3 dB around the Cornell box's light and 57 % more error where the `moving` scene disoccludes (§28).

// #import trace/trace_bindings.wgsl
// #import trace/bsdf.wgsl
// #import trace/environment.wgsl

const EMITTER_ALBEDO_FLOOR: f32 = 0.5;

// A non-delta surface.
fn surface_albedo(m: Material) -> vec3f {
    if HAS_CONDUCTOR && m.kind == MATERIAL_CONDUCTOR {
        return m.reflectance * fresnel_conductor(1.0, m.eta, m.k);
    }
    if HAS_DIELECTRIC && m.kind == MATERIAL_DIELECTRIC {
        return dielectric_transmittance(m);
    }
    if HAS_AREA_LIGHTS && m.is_emissive != 0u {
        return max(m.reflectance, vec3f(EMITTER_ALBEDO_FLOOR));
    }
    return m.reflectance;
}

// What a delta bounce tints the albedo seen through it by: the colour of its sample's weight without the 1/eta²
// by which a refraction scales radiance (a glass's transmittance; a metal mirror's Fresnel colour times its tint;
// 1 for a glass's reflection, whose share of the pixel the lobe's pick sets). So the albedo behind coloured glass
// or a gold mirror carries the colour the light does, and the irradiance the denoiser reads there (colour over
// albedo) is the surface's own, as where it is seen directly (BENCHMARKS.md §50).
fn delta_albedo_tint(bs: BsdfSample) -> vec3f {
    return bs.weight * (bs.eta * bs.eta);
}

// A path that escapes the scene along `dir`.
fn background_albedo(dir: vec3f) -> vec3f {
    return clamp(background_radiance(dir), vec3f(0.0), vec3f(1.0));
}
