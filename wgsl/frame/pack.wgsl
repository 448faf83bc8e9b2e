// Packing the tracer's planes into the networks' planar NCHW f32 inputs, one invocation per pixel.
// Colours go to log space (log1p of the sanitised radiance: NaN/Inf → 0, negatives → 0) so that HDR
// values up to f16's 65504 land near 11 and the FP16 network path keeps precision; the denoiser's colour
// is first demodulated by albedo (frame/albedo.wgsl: it sees irradiance); albedo is clamped
// to [0, 1], normals are mapped by n·0.5 + 0.5, and depth is divided by the frame's max depth (read as
// the bit pattern written by frame/depth_max.wgsl; a frame with no hit packs depth 0). The denoiser's
// last plane says how many samples the pixel's colour averages, as 1/sqrt(spp) (its noise relative to
// one sample's: 1 at 1 spp, 1/16 at 256; a pixel of 0 samples counts as 1).
//   pack_denoiser:   11 ch = log1p RGB/albedo factor, albedo, normal·0.5+0.5, depth/max, 1/sqrt(spp)
//   pack_error:       3 ch = log1p RGB                                     (error predictor)
//   pack_confidence:  8 ch = log1p RGB, log1p reprojected history RGB, depth/max,
//                            reprojected previous depth/max               (confidence predictor)
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

fn log_color(channel: u32, i: u32) -> f32 {
    return log1p_accurate(sanitize(color[channel * pixel_count() + i]));
}

fn normalized_depth(d: f32) -> f32 {
    let frame_max = bitcast<f32>(depth_max_bits);
    if (frame_max <= 0.0) { return 0.0; }
    return sanitize(d) / frame_max;
}

@compute @workgroup_size(8, 8)
fn pack_denoiser(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    let n = pixel_count();
    for (var c = 0u; c < 3u; c++) {
        packed[c * n + i] = log1p_accurate(sanitize(color[c * n + i]) / albedo_factor(albedo[c * n + i]));
        packed[(3u + c) * n + i] = clamp(sanitize(albedo[c * n + i]), 0.0, 1.0);
        packed[(6u + c) * n + i] = clamp(finite_or_zero(normal[c * n + i]) * 0.5 + 0.5, 0.0, 1.0);
    }
    packed[9u * n + i] = normalized_depth(depth[i]);
    packed[10u * n + i] = inverseSqrt(f32(max(spp[i], 1u)));
}

@compute @workgroup_size(8, 8)
fn pack_error(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    for (var c = 0u; c < 3u; c++) { packed[c * pixel_count() + i] = log_color(c, i); }
}

@compute @workgroup_size(8, 8)
fn pack_confidence(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    let n = pixel_count();
    for (var c = 0u; c < 3u; c++) {
        packed[c * n + i] = log_color(c, i);
        packed[(3u + c) * n + i] = log1p_accurate(sanitize(reprojected[c * n + i]));
    }
    packed[6u * n + i] = normalized_depth(depth[i]);
    packed[7u * n + i] = normalized_depth(reprojected[3u * n + i]);
}
