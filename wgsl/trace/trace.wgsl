// Unidirectional path tracing with next-event estimation, following Mitsuba 3's `path` integrator so
// that images agree: emission seen directly (or through delta lobes) counts in full; at every non-delta
// vertex one emitter sample is combined with the BSDF sample by the power heuristic; max_depth counts
// path segments (1 = emission only, 2 = direct lighting); Russian roulette from depth 5 on with
// continuation probability min(max(throughput)·eta², 0.95). Diffuse and metal surfaces are two-sided
// (the shading frame faces the incoming ray); glass keeps its outward normal to tell inside from out.
// Where Mitsuba differs: shadow rays cross thin panes, and crossing one is no vertex and no segment
// (trace/shadow_panes.wgsl).
//
// `main` (uniform passes): one invocation is one pixel; a workgroup of 64 is an 8×8 tile. It takes the
// samples [chunk_start, chunk_start + chunk_size) of this pass's count, numbered after the samples the
// pixel already holds (the spp plane) so extra passes add new, distinct sample indices, and folds their
// mean into the running means of the output planes. Targeted passes (a count per pixel) run the same
// trace_samples and fold_samples from trace/targeted.wgsl over a compacted list of work items.
//
// Each turn of the main loop traces two rays per invocation in one BVH walk (trace_ray_pair): the
// path's next segment and the shadow ray of the next-event estimate made at its previous vertex (whose
// contribution waits until it is known unoccluded). A finished path starts the pixel's next sample in
// the same turn. Invocations outside the image or done with their samples stay in the loop, idle,
// until their whole subgroup is done: the subgroup traversal needs every invocation in the walk.

// #import trace/features.wgsl
// #import trace/trace_bindings.wgsl
// #import accel/bvh.wgsl
// #import trace/bsdf.wgsl
// #import trace/guide_albedo.wgsl
// #import trace/emitters.wgsl
// #import trace/camera.wgsl
// #import trace/surface.wgsl
// #import trace/interior_clear.wgsl

const RR_DEPTH: u32 = 5u;
// Mesa's llvmpipe/lavapipe ends every loop of an invocation once its loops have gone round 65535 times
// in total in one dispatch (an infinite-loop guard), which would cut paths and BVH walks short. So an
// invocation starts no new sample once this loop and its traversal loops have gone round LOOP_BUDGET
// times, leaving the rest for the paths in flight, and records only the samples it completed: the
// pixel stays an unbiased mean, of fewer samples. trace_pass.py sizes chunks to stay well below.
const LOOP_BUDGET: u32 = 49152u;

// Everything one path carries from vertex to vertex, and what it has gathered for its sample.
struct Path {
    origin: vec3f,
    depth: u32,                 // segments traced so far
    dir: vec3f,
    eta_scale: f32,             // product of relative indices crossed (Russian roulette uses eta²)
    throughput: vec3f,
    previous_pdf: f32,          // solid-angle pdf of the BSDF sample that made `dir`
    previous_position: vec3f,   // the vertex that sample left (where its emitter pdf is reckoned)
    previous_importance: f32,   // and the emitter groups' importances summed there (emitters.wgsl)
    radiance: vec3f,
    previous_delta: bool,       // that sample came from a delta lobe (no MIS for what it hits)
    albedo: vec3f,              // while pending, the tint of the delta bounces so far (delta_albedo_tint)
    albedo_pending: bool,       // no non-delta surface met yet
    normal: vec3f,
    linear_depth: f32,
    film: vec2f,
    motion: vec2f,
}

// A next-event estimate waiting for its shadow ray: `contribution` counts if nothing lies within
// `length` along the ray.
struct ShadowRay {
    origin: vec3f,
    length: f32,
    dir: vec3f,
    pending: bool,
    contribution: vec3f,
}

// The shadow ray of a light sample taken at `position`: it leaves the surface at offset_ray_origin and,
// for a sampled point (triangle or point light), aims at that point from the offset origin and stops
// just short of it. Reusing the direction taken from `position` would translate the whole ray by the
// offset; where that moves it toward a triangle emitter's plane, the ray meets the plane earlier by
// offset · |n · n_light| / cos_light, which at grazing emission angles exceeds the 2e-4 shortening
// (sun-room's wall beside its tilted sun: 2.5e-4 against 3.4e-5 at cosine 0.023), and the emitter
// occludes its own sample.
fn shadow_ray_to_light(position: vec3f, geometric_normal: vec3f, light: EmitterSample,
                       contribution: vec3f) -> ShadowRay {
    let origin = offset_ray_origin(position, geometric_normal, light.direction);
    if light.distance >= FAR_AWAY {
        return ShadowRay(origin, FAR_AWAY, light.direction, true, contribution);
    }
    let to_light = position + light.direction * light.distance - origin;
    let distance = length(to_light);
    return ShadowRay(origin, distance * (1.0 - 2e-4), to_light / distance, true, contribution);
}

fn start_path(sampler: ptr<function, Sampler>, pixel_corner: vec2f) -> Path {
    let film = pixel_corner + next_2d(sampler);
    let ray = camera_ray(film, sampler);
    return Path(ray.origin, 0u, ray.dir, 1.0, vec3f(1.0), 0.0, ray.origin,
                0.0, vec3f(0.0), true, vec3f(1.0), WRITE_AOVS, vec3f(0.0), 0.0, film, vec2f(0.0));
}

// Shades where the path's last segment landed (`traced`), leaving the next-event estimate made there in
// `shadow` and the next segment in `path`; returns false once the path has ended.
fn extend_path(path: ptr<function, Path>, sampler: ptr<function, Sampler>, traced: RayPairHit,
               shadow: ptr<function, ShadowRay>) -> bool {
    let hit = traced.hit;
    let origin = (*path).origin;
    let dir = (*path).dir;
    let depth = (*path).depth;
    if hit.prim == NO_HIT {
        if WRITE_AOVS && (*path).albedo_pending {
            (*path).albedo *= background_albedo(dir);
            (*path).albedo_pending = false;
        }
        if HAS_ANALYTIC_LIGHTS && params.background_share > 0.0 {
            var weight = 1.0;
            if !(*path).previous_delta {
                let light_pdf = background_emitter_pdf((*path).previous_position, (*path).previous_importance, dir);
                weight = power_heuristic((*path).previous_pdf, light_pdf);
            }
            (*path).radiance += (*path).throughput * background_radiance(dir) * weight;
        }
        if WRITE_AOVS && HAS_MOTION && depth == 0u && !(SHADOWS_CROSS_PANES && (*path).linear_depth != 0.0) {
            (*path).motion = previous_film_position(dir, (*path).film) - (*path).film;
        }
        return false;
    }
    let geometric_normal = traced.geometric_normal;
    let position = origin + hit.t * dir;
    let material = surface_material(materials[tri_material(hit.prim)], hit);
    let cos_front = -dot(geometric_normal, dir);
    let interior = interior_transmittance(material, cos_front, hit.t);
    (*path).throughput *= interior;
    if WRITE_AOVS && (*path).albedo_pending {
        (*path).albedo *= interior;
    }

    if HAS_AREA_LIGHTS && material.is_emissive != 0u && cos_front > 0.0 {
        var weight = 1.0;
        if !(*path).previous_delta {
            // (past a crossed pane the light is as far as the vertex that sampled the way to it)
            let light_distance = select(hit.t, distance((*path).previous_position, position), SHADOWS_CROSS_PANES);
            let light_pdf = triangle_emitter_pdf((*path).previous_position, (*path).previous_importance, hit.prim,
                                                 light_distance, cos_front);
            weight = power_heuristic((*path).previous_pdf, light_pdf);
        }
        let emitted = material.emission * triangle_emission_color(hit.prim, hit.u, hit.v);
        (*path).radiance += (*path).throughput * emitted * weight;
    }

    let normals = shading_normals_at(hit, geometric_normal, material, dir);
    let shading_normal = normals.mapped;
    if WRITE_AOVS {
        // the first hit (a crossed pane keeps depth 0, its linear depth written)
        if depth == 0u && !(SHADOWS_CROSS_PANES && (*path).linear_depth != 0.0) {
            (*path).normal = shading_normal;
            (*path).linear_depth = dot(position - params.camera_origin, params.camera_forward);
            if HAS_MOTION {
                let before = previous_position(hit.prim, hit.u, hit.v, position);
                let film = (*path).film;
                (*path).motion = previous_film_position(before - params.previous_origin, film) - film;
            }
        }
        if (*path).albedo_pending && !material_is_delta(material) {
            (*path).albedo *= surface_albedo(material);
            (*path).albedo_pending = false;
        }
    }
    // A thin pane crossed by its transmission lobe is no vertex of the path (trace/shadow_panes.wgsl): no depth, no
    // MIS, so paths reach what light samples reach through it; its reflection is one.
    let pane = SHADOWS_CROSS_PANES && material.kind == MATERIAL_THIN_DIELECTRIC;
    if depth + 1u >= params.max_depth && !pane {
        return false;
    }

    let frame = frame_from_normal(shading_normal);
    let wi = to_local(frame, -dir);

    var importance_total = 0.0;
    if !material_is_delta(material) {
        let pick = pick_emitter(position, next_1d(sampler));
        importance_total = pick.importance_total;
        let light = sample_emitter(pick, position, next_2d(sampler));
        if any(light.value > vec3f(0.0)) {
            let wo = to_local(frame, light.direction);
            let f = bsdf_eval(material, wi, wo);
            let mapped = normal_map_weight(normals, light.direction);
            if any(f.value > vec3f(0.0)) && mapped > 0.0 {
                let weight = select(power_heuristic(light.pdf, f.pdf), 1.0, light.pdf == 0.0);
                *shadow = shadow_ray_to_light(position, geometric_normal, light,
                                              (*path).throughput * f.value * light.value * (weight * mapped));
            }
        }
    }

    let u_lobe = next_1d(sampler);
    let bs = bsdf_sample(material, wi, u_lobe, next_2d(sampler));
    let next_dir = normalize(to_world(frame, bs.wo));
    let mapped = normal_map_weight(normals, next_dir);
    if all(bs.weight == vec3f(0.0)) || mapped == 0.0 {
        return false;
    }
    let crossed = pane && bs.wo.z < 0.0;
    if pane && !crossed && depth + 1u >= params.max_depth {
        return false;
    }
    var throughput = (*path).throughput * bs.weight * mapped;
    if WRITE_AOVS && (*path).albedo_pending {      // (so the bounce is a delta one)
        (*path).albedo *= delta_albedo_tint(bs);
    }
    let eta_scale = (*path).eta_scale * bs.eta;
    (*path).dir = next_dir;
    (*path).origin = offset_ray_origin(position, geometric_normal, next_dir);
    if crossed {
        (*path).throughput = throughput;
        return true;
    }
    (*path).previous_pdf = bs.pdf;
    (*path).previous_position = position;
    (*path).previous_importance = importance_total;
    (*path).previous_delta = bs.is_delta;
    (*path).eta_scale = eta_scale;
    (*path).depth = depth + 1u;
    if depth + 1u >= RR_DEPTH {
        let continue_probability = min(max(throughput.x, max(throughput.y, throughput.z)) * eta_scale * eta_scale, 0.95);
        if next_1d(sampler) >= continue_probability {
            return false;
        }
        throughput /= continue_probability;
    }
    (*path).throughput = throughput;
    return true;
}

// Running mean of `count_before` values updated with `batch_sum` over `batch_count` new ones.
fn fold_mean(mean: f32, batch_sum: f32, count_before: f32, batch_count: f32) -> f32 {
    return mean + (batch_sum - batch_count * mean) / (count_before + batch_count);
}

// What one invocation's samples of a pixel add up to: sums over the samples completed, and their count.
struct SampleSums {
    radiance: vec3f,
    count: u32,
    albedo: vec3f,
    depth: f32,
    normal: vec3f,
    motion: vec2f,
}

fn add_sums(a: SampleSums, b: SampleSums) -> SampleSums {
    return SampleSums(a.radiance + b.radiance, a.count + b.count, a.albedo + b.albedo, a.depth + b.depth,
                      a.normal + b.normal, a.motion + b.motion);
}

// Traces `taken` samples of `pixel` (film position `xy`), numbered first_index, first_index + 1, … in
// its sequence (a pixel's sample index is its own: the same index gives the same path whichever
// invocation traces it). Every invocation of a subgroup calls it together; one with nothing to take
// (taken 0) idles in the loop until its subgroup is done.
fn trace_samples(pixel: u32, xy: vec2u, first_index: u32, taken: u32) -> SampleSums {
    var sums = SampleSums(vec3f(0.0), 0u, vec3f(0.0), 0.0, vec3f(0.0), vec2f(0.0));
    // Path regeneration: when a path ends the invocation starts its next sample in the same loop, so
    // the SIMD lanes of a subgroup stay busy until all of them have traced all their samples, instead
    // of each sample waiting for the longest path of its subgroup.
    let pixel_corner = vec2f(xy);
    var tracing = taken > 0u;
    var sampler = sampler_start(pixel, first_index, params.seed);
    var path = start_path(&sampler, pixel_corner);
    var shadow = ShadowRay(vec3f(0.0), 0.0, vec3f(0.0, 0.0, 1.0), false, vec3f(0.0));
    var loop_passes = 0u;
    loop {
        if !packet_any(tracing || shadow.pending) {
            break;
        }
        let traced = trace_ray_pair(path.origin, path.dir, select(0.0, FAR_AWAY, tracing), shadow.origin,
                                    shadow.dir, shadow.length, shadow.pending);
        loop_passes += traced.loop_passes + 1u;
        // a non-finite contribution (a degenerate configuration) is dropped rather than poisoning the pixel
        if shadow.pending && !traced.occluded && is_finite_vec3(shadow.contribution) {
            sums.radiance += select(shadow.contribution, shadow.contribution * traced.shadow_tint, SHADOWS_CROSS_PANES);
        }
        shadow.pending = false;
        if tracing && !extend_path(&path, &sampler, traced, &shadow) {
            sums.radiance += select(vec3f(0.0), path.radiance, is_finite_vec3(path.radiance));
            if WRITE_AOVS {
                sums.albedo += select(path.albedo, vec3f(0.0), path.albedo_pending);   // 0: lost in the chain
                sums.normal += path.normal;
                sums.depth += path.linear_depth;
                sums.motion += path.motion;
            }
            sums.count += 1u;
            tracing = sums.count < taken && loop_passes < LOOP_BUDGET;
            sampler = sampler_start(pixel, first_index + sums.count, params.seed);
            path = start_path(&sampler, pixel_corner);
        }
    }
    return sums;
}

// Folds `sums` (at least one sample) into the running means of `pixel`, which hold `held` samples.
fn fold_samples(pixel: u32, held: u32, sums: SampleSums) {
    let plane = params.width * params.height;
    let before = f32(held);
    let batch = f32(sums.count);   // the samples completed: fewer than asked where LOOP_BUDGET ran out
    for (var c = 0u; c < 3u; c += 1u) {
        let at = c * plane + pixel;
        out_radiance[at] = fold_mean(out_radiance[at], sums.radiance[c], before, batch);
    }
    out_spp[pixel] = held + sums.count;
    if WRITE_AOVS {
        let previous_normal = vec3f(out_normal[pixel], out_normal[plane + pixel], out_normal[2u * plane + pixel]);
        let summed_normal = previous_normal * before + sums.normal;
        let magnitude = length(summed_normal);
        let new_normal = select(vec3f(0.0), summed_normal / magnitude, magnitude > 0.0);
        for (var c = 0u; c < 3u; c += 1u) {
            let at = c * plane + pixel;
            out_albedo[at] = fold_mean(out_albedo[at], sums.albedo[c], before, batch);
            out_normal[at] = new_normal[c];
        }
        out_depth[pixel] = fold_mean(out_depth[pixel], sums.depth, before, batch);
        for (var c = 0u; c < 2u; c += 1u) {
            let at = c * plane + pixel;
            out_motion[at] = fold_mean(out_motion[at], sums.motion[c], before, batch);
        }
    }
}

// One invocation per pixel of an 8×8 tile: the samples [chunk_start, chunk_start + chunk_size) of the
// pass's pass_samples, numbered after those the pixel holds.
@compute @workgroup_size(TILE * TILE)
fn main(@builtin(workgroup_id) tile: vec3u, @builtin(local_invocation_index) local_index: u32) {
    begin_traversal(local_index);
    let xy = tile_pixel(tile, local_index);
    let inside = xy.x < params.width && xy.y < params.height;
    let pixel = select(0u, xy.y * params.width + xy.x, inside);
    let taken = select(0u, min(params.chunk_size, max(params.pass_samples, params.chunk_start) - params.chunk_start),
                       inside);
    let held = out_spp[pixel];
    let sums = trace_samples(pixel, xy, params.sample_offset + held, taken);
    if inside && sums.count > 0u {
        fold_samples(pixel, held, sums);
    }
}
