// Next-event estimation over the emitter table: pick an entry with the alias table (probability
// proportional to its power, as trace/scene_data.py reckons it), then a point on it: area-uniform on a
// triangle (one-sided: its front face, the side its winding's normal points to), the position of a point
// light, the direction of a directional light, a uniform direction for the constant background. Also
// the solid-angle pdf of having sampled a triangle that a BSDF-sampled ray hit, for multiple importance
// sampling.

// #import trace/features.wgsl
// #import trace/trace_bindings.wgsl
// #import trace/sampling.wgsl

struct EmitterSample {
    direction: vec3f,
    distance: f32,       // to the sampled point; a huge value for directional lights and background
    value: vec3f,        // emitted radiance / pdf (0 when the sample is useless)
    pdf: f32,            // solid-angle pdf including the selection probability; 0 for delta lights
}

const FAR_AWAY: f32 = 3.0e38;

fn pick_emitter(u: f32) -> u32 {
    let n = params.emitter_count;
    let scaled = u * f32(n);
    let i = min(u32(scaled), n - 1u);
    let entry = emitters[i];
    return select(entry.alias_index, i, scaled - f32(i) < entry.alias_threshold);
}

fn sample_triangle_emitter(e: Emitter, x: vec3f, u: vec2f) -> EmitterSample {
    let b = square_to_triangle(u);
    let y = e.position + b.x * e.edge1 + b.y * e.edge2;
    let n = normalize(cross(e.edge1, e.edge2));
    let offset = y - x;
    let dist2 = dot(offset, offset);
    let dist = sqrt(dist2);
    let dir = offset / dist;
    let cos_light = -dot(n, dir);
    if cos_light <= 0.0 || dist2 == 0.0 {
        return EmitterSample(dir, dist, vec3f(0.0), 0.0);
    }
    let pdf = e.pmf / e.area * dist2 / cos_light;
    return EmitterSample(dir, dist, e.radiance / pdf, pdf);
}

fn sample_emitter(x: vec3f, u_pick: f32, u: vec2f) -> EmitterSample {
    let e = emitters[pick_emitter(u_pick)];
    if !HAS_ANALYTIC_LIGHTS || e.kind == EMITTER_TRIANGLE {
        return sample_triangle_emitter(e, x, u);
    }
    if e.kind == EMITTER_POINT {
        let offset = e.position - x;
        let dist2 = dot(offset, offset);
        let dist = sqrt(dist2);
        return EmitterSample(offset / dist, dist, e.radiance / (e.pmf * dist2), 0.0);
    }
    if e.kind == EMITTER_DIRECTIONAL {
        return EmitterSample(-normalize(e.edge1), FAR_AWAY, e.radiance / e.pmf, 0.0);
    }
    let dir = square_to_uniform_sphere(u);
    let pdf = e.pmf * INV_FOUR_PI;
    return EmitterSample(dir, FAR_AWAY, e.radiance / pdf, pdf);
}

// Solid-angle pdf with which sample_emitter would pick the point a ray from x hit on triangle `prim`
// at distance t, whose front face it hit with cosine cos_light.
fn triangle_emitter_pdf(prim: u32, t: f32, cos_light: f32) -> f32 {
    return triangle_emitter_density[prim] * t * t / cos_light;
}
