// Noise-free auxiliary features for the denoiser (Intel OIDN's documentation asks for them: the network
// takes whatever the albedo plane holds for texture). The albedo AOV is the first non-delta surface seen
// through mirrors and smooth glass; the path tracer estimates it with its own paths, one per sample, so at
// 1 spp every pixel behind glass shows either the reflected or the refracted surface, picked by Fresnel at
// random: speckle the network reproduces. This pass overwrites the albedo plane with an estimate of that
// quantity from AUX_SAMPLES paths per pixel that follow only the delta chain (pixel jitter, then delta
// lobes; no lights, no shading), which costs a few primary rays per sample instead of full paths. A pixel
// whose first AUX_SAMPLES paths meet a mirror or smooth glass goes on to AUX_DELTA_SAMPLES (n), and its
// lobes are not left to chance: at a path's first smooth-glass bounce the sample's number picks the lobe
// (samples 0 .. k − 1 reflect, k = F·n rounded and kept within 1 .. n − 1 for Fresnel reflectance F; a thin pane's
// F is its two faces' together, thin_dielectric_reflectance) and
// weighs it by its share (F·n / k reflected, (1 − F)·n / (n − k) refracted). Where F and what lies behind
// vary little across the pixel (a pane, a flat face) its samples then add up to F·(reflected albedo) +
// (1 − F)·(refracted albedo) with no lobe noise left; elsewhere the estimate stays unbiased over the
// jitter. At later glass bounces a path takes the more likely lobe, weight 1: what a slab's inner
// reflections reach is mostly what its transmission reaches, and random picks there brought the speckle
// back (BENCHMARKS.md §15, which also has halving the samples between the lobes at the first bounces).
// Only pixels behind mirrors and glass take the extra samples (a pixel seen directly varies only by its
// jitter at edges). (The count depends on what the first paths met, so at the rim of a glass object the
// average leans slightly towards its delta side.)
// Albedo as the tracer takes it (trace/guide_albedo.wgsl: an escape's is the background's radiance; what is seen
// through a delta bounce tinted by its colour, delta_albedo_tint, and through absorbing glass by what it keeps);
// running out of max_depth inside the chain counts as albedo 0, as in the tracer. Like
// the tracer (LOOP_BUDGET in trace/trace.wgsl), an invocation starts no new sample once its loops have
// gone round AUX_LOOP_BUDGET times (lavapipe ends loops at 65535 turns per dispatch) and averages the
// samples it completed.
// Through a thin lens (params.lens_radius > 0) a pixel out of focus mixes what the aperture's points see,
// its first hits' normals and depths as much as its albedo, so the pass also overwrites the normal and depth
// planes with its samples' means (the tracer's at its own few samples are as noisy as its albedo).

// #import trace/features.wgsl
// #import trace/trace_bindings.wgsl
// #import accel/bvh.wgsl
// #import trace/bsdf.wgsl
// #import trace/guide_albedo.wgsl
// #import trace/camera.wgsl
// #import trace/surface.wgsl
// #import trace/interior_clear.wgsl

override AUX_SAMPLES: u32 = 4u;
override AUX_DELTA_SAMPLES: u32 = 8u;   // at least AUX_SAMPLES (trace_pass.py sees to it)
const AUX_SEED_SALT: u32 = 0x5bd1e995u;   // aux samples draw numbers no trace sample draws
const AUX_FAR: f32 = 3.0e38;
const AUX_LOOP_BUDGET: u32 = 49152u;

@compute @workgroup_size(TILE * TILE)
fn aux(@builtin(workgroup_id) tile: vec3u, @builtin(local_invocation_index) local_index: u32) {
    begin_traversal(local_index);
    let xy = tile_pixel(tile, local_index);
    let inside = xy.x < params.width && xy.y < params.height;
    let pixel = select(0u, xy.y * params.width + xy.x, inside);
    let seed = params.seed ^ AUX_SEED_SALT;
    var sampler = sampler_start(pixel, 0u, seed);
    var ray = camera_ray(vec2f(xy) + next_2d(&sampler), &sampler);
    var origin = ray.origin;
    var dir = ray.dir;
    var depth = 0u;
    var index = 0u;
    var sum = vec3f(0.0);
    var sampling = inside;
    var met_delta = false;
    var loop_passes = 0u;
    var weight = vec3f(1.0);   // of the current sample's albedo: its first glass lobe's share, times its tints
    var met_glass = false;     // has the current sample met smooth glass yet?
    let lens = params.lens_radius > 0.0;
    var normal_sum = vec3f(0.0);   // of the samples' first hits (through a lens)
    var depth_sum = 0.0;
    // Every invocation stays in the loop until its whole subgroup is done (the subgroup traversal walks
    // the BVH as one packet); finished ones query with t_max 0.
    loop {
        if !packet_any(sampling) {
            break;
        }
        let traced = trace_ray_pair(origin, dir, select(0.0, AUX_FAR, sampling), origin, dir, 0.0, false);
        let hit = traced.hit;
        loop_passes += traced.loop_passes + 1u;
        if sampling {
            var sample_done = true;
            if hit.prim != NO_HIT {
                let material = surface_material(materials[tri_material(hit.prim)], hit);
                let delta = material_is_delta(material);
                weight *= interior_transmittance(material, -dot(traced.geometric_normal, dir), hit.t);
                if lens && depth == 0u {   // as the tracer's normal and depth planes take the first hit
                    normal_sum += shading_normal_at(hit, traced.geometric_normal, material, dir);
                    depth_sum += dot(origin + hit.t * dir - params.camera_origin, params.camera_forward);
                }
                met_delta = met_delta || delta;
                if !delta {
                    sum += weight * surface_albedo(material);
                } else if depth + 1u < params.max_depth {
                    let geometric_normal = traced.geometric_normal;
                    let frame = frame_from_normal(shading_normal_at(hit, geometric_normal, material, dir));
                    let wi = to_local(frame, -dir);
                    var take_reflection = true;   // a mirror's only lobe
                    let thin = material.kind == MATERIAL_THIN_DIELECTRIC;
                    if HAS_DIELECTRIC && (material.kind == MATERIAL_DIELECTRIC || thin) {
                        let reflectance = select(fresnel_dielectric(wi.z, material.ior).reflectance,
                                                 thin_dielectric_reflectance(wi.z, material.ior), thin);
                        take_reflection = reflectance > 0.5;   // past the first glass bounce: the major lobe
                        if !met_glass && AUX_DELTA_SAMPLES >= 2u {
                            // the sample's number picks the lobe: the first `reflected` samples reflect
                            let n = f32(AUX_DELTA_SAMPLES);
                            let reflected = clamp(round(reflectance * n), 1.0, n - 1.0);
                            take_reflection = f32(index) < reflected;
                            weight *= select((1.0 - reflectance) * n / (n - reflected), reflectance * n / reflected,
                                             take_reflection);
                        }
                        met_glass = true;
                    }
                    // (dielectric_sample reflects when its u_lobe is below F: 0 does unless F = 0, 1 does not unless F = 1;
                    // a lobe of share 0 ends the sample below)
                    let bs = bsdf_sample(material, wi, select(1.0, 0.0, take_reflection), next_2d(&sampler));
                    if any(weight > vec3f(0.0)) && any(bs.weight != vec3f(0.0)) {
                        weight *= delta_albedo_tint(bs);
                        let position = origin + hit.t * dir;
                        dir = normalize(to_world(frame, bs.wo));
                        origin = offset_ray_origin(position, geometric_normal, dir);
                        depth += 1u;
                        sample_done = false;
                    }
                }
            } else {
                sum += weight * background_albedo(dir);
            }
            if sample_done {
                index += 1u;
                sampling = index < select(AUX_SAMPLES, AUX_DELTA_SAMPLES, met_delta)
                           && loop_passes < AUX_LOOP_BUDGET;
                sampler = sampler_start(pixel, index, seed);
                ray = camera_ray(vec2f(xy) + next_2d(&sampler), &sampler);
                origin = ray.origin;
                dir = ray.dir;
                depth = 0u;
                weight = vec3f(1.0);
                met_glass = false;
            }
        }
    }
    if !inside || index == 0u {
        return;
    }
    let plane = params.width * params.height;
    let albedo = sum / f32(index);
    for (var c = 0u; c < 3u; c += 1u) {
        out_albedo[c * plane + pixel] = albedo[c];
    }
    if lens {
        let magnitude = length(normal_sum);
        let normal = select(vec3f(0.0), normal_sum / magnitude, magnitude > 0.0);
        for (var c = 0u; c < 3u; c += 1u) {
            out_normal[c * plane + pixel] = normal[c];
        }
        out_depth[pixel] = depth_sum / f32(index);
    }
}
