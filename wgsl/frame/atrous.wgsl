// The edge-aware à-trous filter over the denoised radiance (wgpu_rt/frame/atrous.py says why and is the
// reference). Each pass is a 5×5 B3-spline kernel with taps STEP pixels apart (indices clamped at the
// frame's edges), each tap weighed by exp(−Σ d²/2σ²) over the differences in display luminance of the
// pass's input (σ narrowing with the centre's samples past FADE_SPP), albedo, normal and depth relative to
// the centre's. What a tap reads is laid out once per pixel, side by side (three vec4f), so a tap is three
// adjacent loads and one exp:
//   atrous_prepare: DENOISED → `work_out` (radiance clamped to FILTER_LIMIT, its display luminance) and
//                   `guides` (albedo, depth; normal, 1/(2σ²) of the luminance), sanitised
//   atrous_step:    `work_in` → `work_out`, one pass; atrous_last: the last pass, into DENOISED
// One invocation per pixel.
// #import frame/common.wgsl

override STEP: i32 = 1;
override SIGMA_LUMINANCE: f32;   // up to FADE_SPP samples at the centre pixel, then · sqrt(FADE_SPP / spp)
override FADE_SPP: f32;
override SIGMA_ALBEDO: f32;
override SIGMA_NORMAL: f32;
override SIGMA_DEPTH: f32;
override DEPTH_FLOOR: f32;
override FILTER_LIMIT: f32;
override KEY_RATIO: f32;                // pack.py's: exposure[3] · KEY_RATIO is the frame's key over STEPS_KEY
override LUMINANCE_FACTOR_LIMIT: f32;
const DISPLAY_GAMMA: f32 = 2.2;

@group(0) @binding(0) var<storage, read_write> denoised: array<f32>;   // 3 planes
@group(0) @binding(1) var<storage, read> work_in: array<vec4f>;         // per pixel: radiance, luminance
@group(0) @binding(2) var<storage, read_write> work_out: array<vec4f>;
@group(0) @binding(3) var<storage, read> albedo: array<f32>;            // 3 planes
@group(0) @binding(4) var<storage, read> normal: array<f32>;            // 3 planes
@group(0) @binding(5) var<storage, read> depth: array<f32>;
@group(0) @binding(6) var<storage, read> spp: array<u32>;
@group(0) @binding(7) var<storage, read_write> guides: array<vec4f>;    // per pixel: (albedo, depth), (normal, 1/2σ²)
@group(0) @binding(8) var<storage, read> exposure: array<f32, 4>;        // [3]: the frame's (frame/balance.wgsl)

// The channel mean at the frame's exposure brought to STEPS_KEY, on the metric's display.
fn display_luminance(radiance: vec3f) -> f32 {
    let factor = min(1.0 / (exposure[3] * KEY_RATIO), LUMINANCE_FACTOR_LIMIT);
    let mean = (radiance.x / 3.0 + radiance.y / 3.0 + radiance.z / 3.0) * factor;
    return pow(mean / (1.0 + mean), 1.0 / DISPLAY_GAMMA);
}

@compute @workgroup_size(8, 8)
fn atrous_prepare(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let n = pixel_count();
    let i = pixel_index(id);
    let radiance = min(vec3f(sanitize(denoised[i]), sanitize(denoised[n + i]), sanitize(denoised[2u * n + i])),
                       vec3f(FILTER_LIMIT));
    work_out[i] = vec4f(radiance, display_luminance(radiance));
    let sigma = SIGMA_LUMINANCE * sqrt(FADE_SPP / max(f32(spp[i]), FADE_SPP));
    let depth_value = min(sanitize(depth[i]), FILTER_LIMIT);   // 1 / depth stays a normal float
    guides[2u * i] = vec4f(sanitize(albedo[i]), sanitize(albedo[n + i]), sanitize(albedo[2u * n + i]), depth_value);
    guides[2u * i + 1u] = vec4f(finite_or_zero(normal[i]), finite_or_zero(normal[n + i]),
                                finite_or_zero(normal[2u * n + i]), 1.0 / (2.0 * sigma * sigma));
}

fn b3(k: i32) -> f32 {
    return select(select(0.0625, 0.25, abs(k) == 1), 0.375, k == 0);
}

// One pass at pixel `id`: the weighted mean of `work_in` over the 5×5 taps.
fn filter_at(id: vec3u) -> vec3f {
    let i = pixel_index(id);
    let centre = work_in[i];
    let surface = guides[2u * i];
    let facing = guides[2u * i + 1u];
    let inverse_depth = 1.0 / max(surface.w, DEPTH_FLOOR);   // depth differences relative to the centre's
    let albedo_scale = 1.0 / (2.0 * SIGMA_ALBEDO * SIGMA_ALBEDO);
    let normal_scale = 1.0 / (2.0 * SIGMA_NORMAL * SIGMA_NORMAL);
    let depth_scale = 1.0 / (2.0 * SIGMA_DEPTH * SIGMA_DEPTH);
    var total = vec3f(0.0);
    var weights = 0.0;
    for (var dy = -2; dy <= 2; dy++) {
        let y = u32(clamp(i32(id.y) + dy * STEP, 0, i32(HEIGHT) - 1));
        for (var dx = -2; dx <= 2; dx++) {
            let j = y * WIDTH + u32(clamp(i32(id.x) + dx * STEP, 0, i32(WIDTH) - 1));
            let tap = work_in[j];
            let tap_surface = guides[2u * j];
            let tap_facing = guides[2u * j + 1u];
            let dl = tap.w - centre.w;
            let da = tap_surface.xyz - surface.xyz;
            let dn = tap_facing.xyz - facing.xyz;
            let dd = (tap_surface.w - surface.w) * inverse_depth;
            let exponent = dl * dl * facing.w + dot(da, da) * albedo_scale + dot(dn, dn) * normal_scale
                         + dd * dd * depth_scale;
            let weight = b3(dx) * b3(dy) * exp(-exponent);
            total += weight * tap.xyz;
            weights += weight;
        }
    }
    return total / weights;   // the centre's own weight keeps `weights` ≥ 0.375²
}

@compute @workgroup_size(8, 8)
fn atrous_step(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let radiance = filter_at(id);
    work_out[pixel_index(id)] = vec4f(radiance, display_luminance(radiance));
}

@compute @workgroup_size(8, 8)
fn atrous_last(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let radiance = filter_at(id);
    let n = pixel_count();
    let i = pixel_index(id);
    for (var c = 0u; c < 3u; c++) { denoised[c * n + i] = radiance[c]; }
}
