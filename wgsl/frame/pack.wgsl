// Packing the tracer's planes into the networks' planar NCHW f32 inputs, one invocation per pixel.
// Colours go to log space (log1p of the sanitised radiance: NaN/Inf → 0, negatives → 0) so that HDR
// values up to f16's 65504 land near 11 and the FP16 network path keeps precision; the denoiser's colour
// is first demodulated by albedo (frame/albedo.wgsl: it sees irradiance) and white-balanced by the frame's
// gains (frame/balance.wgsl, found earlier in the same encoder); albedo is clamped
// to [0, 1], normals are mapped by n·0.5 + 0.5, and depth is divided by the frame's max depth (read as
// the bit pattern written by frame/depth_max.wgsl; a frame with no hit packs depth 0). The denoiser's
// last plane says how many samples the pixel's colour averages, as 1/sqrt(spp) (its noise relative to
// one sample's: 1 at 1 spp, 1/16 at 256; a pixel of 0 samples counts as 1).
//   pack_denoiser:   11 ch = log1p RGB/(albedo factor·gain), albedo, normal·0.5+0.5, depth/max, 1/sqrt(spp)
//   pack_denoiser_level: the same for the frame averaged over LEVEL_FACTOR² blocks (frame/lowband.wgsl)
//   pack_error:       3 ch = log1p RGB / the probe's gains                  (error predictor; gains of 1, or
//                            its exposure scale from frame/balance.wgsl without DEMODULATE)
//   pack_confidence:  8 ch = log1p RGB, log1p reprojected history RGB (both / the gains, as pack_error),
//                            depth/max, reprojected previous depth/max    (confidence predictor)
// #import frame/common.wgsl
// #import frame/albedo.wgsl

@group(0) @binding(0) var<storage, read> color: array<f32>;
@group(0) @binding(1) var<storage, read> albedo: array<f32>;
@group(0) @binding(2) var<storage, read> normal: array<f32>;
@group(0) @binding(3) var<storage, read> depth: array<f32>;
@group(0) @binding(4) var<storage, read> depth_max_bits: u32;
@group(0) @binding(5) var<storage, read> reprojected: array<f32>;   // frame/temporal.wgsl's 5 planes
@group(0) @binding(6) var<storage, read_write> packed: array<f32>;
@group(0) @binding(7) var<storage, read> spp: array<u32>;
@group(0) @binding(8) var<storage, read> balance: array<f32, 3>;   // frame/balance.wgsl's gains

// log1p of a sanitised colour value divided by the channel's gain (clamped to f32's max first).
fn log_exposed(value: f32, channel: u32) -> f32 {
    return log1p_accurate(min(sanitize(value) / balance[channel], F32_MAX));
}

fn normalized_depth(d: f32) -> f32 {
    let frame_max = bitcast<f32>(depth_max_bits);
    if (frame_max <= 0.0) { return 0.0; }
    return quotient(sanitize(d), frame_max);
}

// The denoiser's 11 input values of pixel i on a canvas of n pixels, from sanitised colour and albedo and
// finite normal components (irradiance beyond f32's range, bright radiance over black albedo, is
// clamped to its max before the log).
fn write_denoiser_input(i: u32, n: u32, rgb: vec3f, albedo_value: vec3f, normal_value: vec3f, d: f32,
                        samples: u32) {
    for (var c = 0u; c < 3u; c++) {
        packed[c * n + i] = log1p_accurate(min(rgb[c] / (albedo_factor(albedo_value[c]) * balance[c]), F32_MAX));
        packed[(3u + c) * n + i] = clamp(albedo_value[c], 0.0, 1.0);
        packed[(6u + c) * n + i] = clamp(normal_value[c] * 0.5 + 0.5, 0.0, 1.0);
    }
    packed[9u * n + i] = normalized_depth(d);
    packed[10u * n + i] = inverseSqrt(f32(max(samples, 1u)));
}

@compute @workgroup_size(8, 8)
fn pack_denoiser(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    let n = pixel_count();
    var rgb: vec3f;
    var albedo_value: vec3f;
    var normal_value: vec3f;
    for (var c = 0u; c < 3u; c++) {
        rgb[c] = sanitize(color[c * n + i]);
        albedo_value[c] = sanitize(albedo[c * n + i]);
        normal_value[c] = finite_or_zero(normal[c * n + i]);
    }
    write_denoiser_input(i, n, rgb, albedo_value, normal_value, depth[i], spp[i]);
}

// The denoiser's input for a coarser level of the frame (frame/lowband.wgsl): one invocation per pixel
// of the ceil(W/f)×ceil(H/f) canvas, f = LEVEL_FACTOR (2, 4, …), packing the mean of the frame pixels in
// its f×f block (fewer at the bottom and right edges): colour, albedo and depth averaged, the normals'
// mean renormalised (0 where they cancel: no component above 1e-6), the block's samples summed, depth
// still divided by the full frame's max.
override LEVEL_FACTOR: u32 = 2u;

@compute @workgroup_size(8, 8)
fn pack_denoiser_level(@builtin(global_invocation_id) id: vec3u) {
    let level_size = (vec2u(WIDTH, HEIGHT) + LEVEL_FACTOR - 1u) / LEVEL_FACTOR;
    if (id.x >= level_size.x || id.y >= level_size.y) { return; }
    let n = pixel_count();
    let first = LEVEL_FACTOR * id.xy;
    let last = min(first + LEVEL_FACTOR, vec2u(WIDTH, HEIGHT));
    let share = 1.0 / f32((last.x - first.x) * (last.y - first.y));   // each term pre-scaled: no overflow
    var rgb = vec3f(0.0);
    var albedo_value = vec3f(0.0);
    var normal_value = vec3f(0.0);
    var d = 0.0;
    var samples = 0u;
    for (var y = first.y; y < last.y; y++) {
        for (var x = first.x; x < last.x; x++) {
            let i = y * WIDTH + x;
            for (var c = 0u; c < 3u; c++) {
                rgb[c] += sanitize(color[c * n + i]) * share;
                albedo_value[c] += sanitize(albedo[c * n + i]) * share;
                normal_value[c] += finite_or_zero(normal[c * n + i]) * share;
            }
            d += sanitize(depth[i]) * share;
            samples += spp[i];
        }
    }
    let largest = max(max(abs(normal_value.x), abs(normal_value.y)), abs(normal_value.z));
    let scaled = vec3f(quotient(normal_value.x, largest), quotient(normal_value.y, largest),
                       quotient(normal_value.z, largest));   // no overflow in the length
    normal_value = select(vec3f(0.0), normalize(scaled), largest > 1e-6);
    write_denoiser_input(id.y * level_size.x + id.x, level_size.x * level_size.y, min(rgb, vec3f(F32_MAX)),
                         albedo_value, normal_value, d, samples);
}

@compute @workgroup_size(8, 8)
fn pack_error(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    for (var c = 0u; c < 3u; c++) { packed[c * pixel_count() + i] = log_exposed(color[c * pixel_count() + i], c); }
}

@compute @workgroup_size(8, 8)
fn pack_confidence(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    let n = pixel_count();
    for (var c = 0u; c < 3u; c++) {
        packed[c * n + i] = log_exposed(color[c * n + i], c);
        packed[(3u + c) * n + i] = log_exposed(reprojected[c * n + i], c);
    }
    packed[6u * n + i] = normalized_depth(depth[i]);
    packed[7u * n + i] = normalized_depth(reprojected[3u * n + i]);
}
