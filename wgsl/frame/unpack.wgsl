// The denoiser's output back to linear radiance: expm1 of its log1p irradiance, remodulated by the
// albedo factor pack_denoiser divided by (frame/albedo.wgsl), read from the albedo plane (ALBEDO_PLANE 0)
// or from the packed input itself (ALBEDO_PLANE 3: a coarser level's, frame/lowband.wgsl), times the
// white-balance gain it divided by (frame/balance.wgsl). NaN/±Inf in the network's output become 0, and
// the log value is clamped to [0, 43] first, so the result is finite (expm1(43) · 1.01 · 3, the largest
// gain, · 2^64, the largest exposure scale, ≈ 2.6e38 < f32 max) and non-negative (a network may undershoot
// below log1p(0) = 0).
// #import frame/common.wgsl
// #import frame/albedo.wgsl

const MAX_LOG_RADIANCE: f32 = 43.0;
override ALBEDO_PLANE: u32 = 0u;

@group(0) @binding(0) var<storage, read> network_output: array<f32>;
@group(0) @binding(1) var<storage, read> albedo: array<f32>;
@group(0) @binding(2) var<storage, read_write> radiance: array<f32>;
@group(0) @binding(3) var<storage, read> balance: array<f32, 3>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    let n = pixel_count();
    var denoised: vec3f;
    for (var c = 0u; c < 3u; c++) {
        let log_irradiance = clamp(finite_or_zero(network_output[c * n + i]), 0.0, MAX_LOG_RADIANCE);
        denoised[c] = expm1_accurate(log_irradiance) * (albedo_factor(albedo[(ALBEDO_PLANE + c) * n + i]) * balance[c]);
    }
    for (var c = 0u; c < 3u; c++) { radiance[c * n + i] = denoised[c]; }
}
