// Next-event estimation over the emitter table: pick an emitter group by an estimate of the irradiance
// it gives at the shading point, mixed with picks by power (trace/scene_data.py's group_probabilities is
// the numpy reference), then an entry within the group with its alias table (in proportion to power),
// then a point on it: area-uniform on a triangle (one-sided: its front face, the side its winding's
// normal points to), the position of a point light, the direction of a directional light, a direction
// toward the background (uniform for a constant one, by an environment map's radiance: environment.wgsl).
// Also the solid-angle pdfs with which the estimate at a point would have sampled what a BSDF-sampled ray
// from there met (a triangle, the background), for multiple importance sampling.

// #import trace/features.wgsl
// #import trace/trace_bindings.wgsl
// #import trace/sampling.wgsl
// #import trace/environment.wgsl
// #import trace/emission_plain.wgsl
// #import accel/bvh.wgsl

struct EmitterSample {
    direction: vec3f,
    distance: f32,       // to the sampled point; a huge value for directional lights and background
    value: vec3f,        // emitted radiance / pdf (0 when the sample is useless)
    pdf: f32,            // solid-angle pdf including the selection probability; 0 for delta lights
}

const FAR_AWAY: f32 = 3.0e38;
const DEFENSIVE_SHARE: f32 = 0.1;   // wgpu_rt.trace.scene_data.DEFENSIVE_SHARE

// The irradiance group g is estimated to give at x: constant for a sun, a sky or the group of everything;
// intensity / d² for a point light; radiance·area / max(d², radius²) for an area light (`power` holds a
// quarter of it for a solid one), times, for a flat one, the cosine at the light bounded over its
// bounding sphere as seen from x, which is 0 behind its plane.
fn group_importance(g: EmitterGroup, x: vec3f) -> f32 {
    if g.kind == GROUP_CONSTANT {
        return g.power;
    }
    let offset = x - g.center;
    let d2 = dot(offset, offset);
    if g.kind == GROUP_POINT {
        return g.power / max(d2, 1e-20);
    }
    let near = g.power / max(d2, g.radius * g.radius);
    if g.kind == GROUP_SOLID {
        return near;
    }
    let height = dot(offset, g.normal);
    if height <= 0.0 {
        return 0.0;
    }
    let distance = sqrt(d2);
    let cos_light = min(height / distance, 1.0);
    let sin_bound = min(g.radius / distance, 1.0);
    let cos_bound = sqrt(max(1.0 - sin_bound * sin_bound, 0.0));
    if cos_light >= cos_bound {
        return near;
    }
    return near * (cos_light * cos_bound + sqrt(max(1.0 - cos_light * cos_light, 0.0)) * sin_bound);
}

fn group_probability_of(importance: f32, total: f32, pmf: f32) -> f32 {
    if total <= 0.0 {
        return pmf;
    }
    return (1.0 - DEFENSIVE_SHARE) * importance / total + DEFENSIVE_SHARE * pmf;
}

// Probability that the estimate at x, whose groups' importances summed to `importance_total` when
// pick_emitter made it, picks group `index`.
fn group_probability(x: vec3f, importance_total: f32, index: u32) -> f32 {
    if !HAS_EMITTER_GROUPS || params.emitter_group_count == 1u {
        return 1.0;
    }
    let group = params.emitter_groups[index];
    return group_probability_of(group_importance(group, x), importance_total, group.pmf);
}

// The entry of the table the estimate at x takes for random number u, the probability of having
// picked its group, and the sum of the groups' importances at x (kept by the path for the multiple-
// importance weight of what its next segment meets, so that it need not loop over the groups again).
struct EmitterPick {
    index: u32,
    group_probability: f32,
    importance_total: f32,
}

fn pick_emitter(x: vec3f, u: f32) -> EmitterPick {
    var first = 0u;                       // one group: it holds the whole table
    var count = params.emitter_count;
    var probability = 1.0;
    var rest = u;       // u rescaled to [0, 1) within the picked group's interval
    var total = 0.0;
    if HAS_EMITTER_GROUPS && params.emitter_group_count > 1u {
        var importance: array<f32, 16>;   // per group (MAX_EMITTER_GROUPS)
        for (var g = 0u; g < params.emitter_group_count; g++) {
            importance[g] = group_importance(params.emitter_groups[g], x);
            total += importance[g];
        }
        var below = 0.0;
        var chosen = params.emitter_group_count;     // none yet
        for (var g = 0u; g < params.emitter_group_count; g++) {
            let p = group_probability_of(importance[g], total, params.emitter_groups[g].pmf);
            // the last group takes what rounding leaves past the sum of the probabilities
            if chosen == params.emitter_group_count && (u < below + p || g + 1u == params.emitter_group_count) {
                chosen = g;
                probability = p;
                rest = min(max(u - below, 0.0) / p, 0.99999994);
            }
            below += p;
        }
        first = params.emitter_groups[chosen].first;
        count = params.emitter_groups[chosen].count;
    }
    let scaled = rest * f32(count);
    let i = min(u32(scaled), count - 1u);
    let entry = emitters[first + i];
    let index = select(entry.alias_index, first + i, scaled - f32(i) < entry.alias_threshold);
    return EmitterPick(index, probability, total);
}

fn sample_triangle_emitter(e: Emitter, pmf: f32, x: vec3f, u: vec2f) -> EmitterSample {
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
    let pdf = pmf / e.area * dist2 / cos_light;
    // a hole of a cut-out emitter gives nothing (as a path through it meets no light), sampled by area all the same
    // (HAS_CUTOUTS: a scene without cut-outs looks nothing up on this path)
    if HAS_CUTOUTS && triangle_cut_away(placed_triangle(e.triangle).stored, b.x, b.y) {
        return EmitterSample(dir, dist, vec3f(0.0), pdf);
    }
    return EmitterSample(dir, dist, e.radiance * emission_color(e.emission_image, e.triangle, b.x, b.y) / pdf, pdf);
}

// The share of a point light's intensity it sends along unit direction `out`: 1 for a point light (no
// axis); for a spot light (Mitsuba's spot) 1 within its beam width of its axis, falling linearly in angle to 0
// at its cutoff angle (numpy reference: wgpu_rt.scene.model.SpotLight.falloff).
fn spot_falloff(e: Emitter, out: vec3f) -> f32 {
    if all(e.edge1 == vec3f(0.0)) {
        return 1.0;
    }
    let angle = acos(clamp(dot(out, e.edge1), -1.0, 1.0));
    let cutoff = e.edge2.x;
    let beam = e.edge2.y;
    return select(clamp((cutoff - angle) / (cutoff - beam), 0.0, 1.0), 1.0, angle <= beam);
}

// A point on the entry `pick` took, seen from x.
fn sample_emitter(pick: EmitterPick, x: vec3f, u: vec2f) -> EmitterSample {
    let e = emitters[pick.index];
    let pmf = pick.group_probability * e.share;
    if !HAS_ANALYTIC_LIGHTS || e.kind == EMITTER_TRIANGLE {
        return sample_triangle_emitter(e, pmf, x, u);
    }
    if e.kind == EMITTER_POINT {
        let offset = e.position - x;
        let dist2 = dot(offset, offset);
        let dist = sqrt(dist2);
        return EmitterSample(offset / dist, dist, e.radiance * spot_falloff(e, -offset / dist) / (pmf * dist2), 0.0);
    }
    if e.kind == EMITTER_DIRECTIONAL {
        return EmitterSample(-normalize(e.edge1), FAR_AWAY, e.radiance / pmf, 0.0);
    }
    let sky = sample_sky(u);
    let pdf = pmf * sky.pdf;
    if pdf <= 0.0 {
        return EmitterSample(sky.dir, FAR_AWAY, vec3f(0.0), 0.0);
    }
    return EmitterSample(sky.dir, FAR_AWAY, background_radiance(sky.dir) / pdf, pdf);
}

// Solid-angle pdf with which the estimate at x (importance_total: its pick's) would pick the point a ray
// from x hit on triangle `prim` at distance t, whose front face it hit with cosine cos_light (0 for a
// triangle of no area, which has no entry).
fn triangle_emitter_pdf(x: vec3f, importance_total: f32, prim: u32, t: f32, cos_light: f32) -> f32 {
    let entry = triangle_emitter[prim];
    if entry == 0u {
        return 0.0;
    }
    let e = emitters[entry - 1u];
    return group_probability(x, importance_total, e.group) * e.share / e.area * t * t / cos_light;
}

// Solid-angle pdf with which the estimate at x (importance_total: its pick's) would pick a direction to
// the background.
fn background_emitter_pdf(x: vec3f, importance_total: f32, dir: vec3f) -> f32 {
    return group_probability(x, importance_total, params.background_group) * params.background_share * sky_pdf(dir);
}
