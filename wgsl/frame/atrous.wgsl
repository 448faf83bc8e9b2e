// One pass of the edge-aware à-trous filter over the denoised radiance (wgpu_rt/frame/atrous.py says why
// and is the reference): a 5×5 B3-spline kernel with taps STEP pixels apart (indices clamped at the
// frame's edges), each tap weighed by exp(−Σ d²/2σ²) over the differences in display luminance of
// `source` (σ narrowing with the centre's samples past FADE_SPP), albedo, normal and depth relative to the
// centre's; `filtered` = the weighted mean of `source`.
// One invocation per pixel.
// #import frame/common.wgsl

override STEP: i32;
override SIGMA_LUMINANCE: f32;   // up to FADE_SPP samples at the centre pixel, then · sqrt(FADE_SPP / spp)
override FADE_SPP: f32;
override SIGMA_ALBEDO: f32;
override SIGMA_NORMAL: f32;
override SIGMA_DEPTH: f32;
override DEPTH_FLOOR: f32;
override FILTER_LIMIT: f32;
const DISPLAY_GAMMA: f32 = 2.2;

@group(0) @binding(0) var<storage, read> source: array<f32>;        // 3 planes
@group(0) @binding(1) var<storage, read_write> filtered: array<f32>;  // 3 planes
@group(0) @binding(2) var<storage, read> albedo: array<f32>;        // 3 planes
@group(0) @binding(3) var<storage, read> normal: array<f32>;        // 3 planes
@group(0) @binding(4) var<storage, read> depth: array<f32>;
@group(0) @binding(5) var<storage, read> spp: array<u32>;

struct Guide { radiance: vec3f, luminance: f32, albedo: vec3f, normal: vec3f, depth: f32 }

fn guide_at(i: u32) -> Guide {
    let n = pixel_count();
    let radiance = min(vec3f(sanitize(source[i]), sanitize(source[n + i]), sanitize(source[2u * n + i])),
                       vec3f(FILTER_LIMIT));
    let mean = radiance.x / 3.0 + radiance.y / 3.0 + radiance.z / 3.0;
    return Guide(radiance, pow(mean / (1.0 + mean), 1.0 / DISPLAY_GAMMA),
                 vec3f(sanitize(albedo[i]), sanitize(albedo[n + i]), sanitize(albedo[2u * n + i])),
                 vec3f(finite_or_zero(normal[i]), finite_or_zero(normal[n + i]), finite_or_zero(normal[2u * n + i])),
                 sanitize(depth[i]));
}

fn b3(k: i32) -> f32 {
    return select(select(0.0625, 0.25, abs(k) == 1), 0.375, k == 0);
}

@compute @workgroup_size(8, 8)
fn atrous_step(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let n = pixel_count();
    let centre = guide_at(pixel_index(id));
    let depth_scale = max(centre.depth, DEPTH_FLOOR);
    let sigma = SIGMA_LUMINANCE * sqrt(FADE_SPP / max(f32(spp[pixel_index(id)]), FADE_SPP));
    var total = vec3f(0.0);
    var weights = 0.0;
    for (var dy = -2; dy <= 2; dy++) {
        let y = u32(clamp(i32(id.y) + dy * STEP, 0, i32(HEIGHT) - 1));
        for (var dx = -2; dx <= 2; dx++) {
            let x = u32(clamp(i32(id.x) + dx * STEP, 0, i32(WIDTH) - 1));
            let tap = guide_at(y * WIDTH + x);
            let dl = tap.luminance - centre.luminance;
            let da = tap.albedo - centre.albedo;
            let dn = tap.normal - centre.normal;
            let dd = (tap.depth - centre.depth) / depth_scale;
            let exponent = dl * dl / (2.0 * sigma * sigma)
                         + dot(da, da) / (2.0 * SIGMA_ALBEDO * SIGMA_ALBEDO)
                         + dot(dn, dn) / (2.0 * SIGMA_NORMAL * SIGMA_NORMAL)
                         + dd * dd / (2.0 * SIGMA_DEPTH * SIGMA_DEPTH);
            let weight = b3(dx) * b3(dy) * exp(-exponent);
            total += weight * tap.radiance;
            weights += weight;
        }
    }
    let i = pixel_index(id);
    let out = total / weights;   // the centre's own weight keeps `weights` ≥ 0.375²
    for (var c = 0u; c < 3u; c++) { filtered[c * n + i] = out[c]; }
}
