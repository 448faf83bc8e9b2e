// Albedo demodulation shared by frame_pack (divide) and frame_unpack (multiply back): the denoiser works
// on irradiance, colour / (albedo + ALBEDO_EPSILON), with albedo sanitised and clamped to [0, 1]; the
// epsilon keeps black albedo finite (an escape carries the background's radiance as albedo,
// trace/guide_albedo.wgsl). pack.py's ALBEDO_EPSILON is the same value.
// #import frame/common.wgsl

const ALBEDO_EPSILON: f32 = 0.01;

fn albedo_factor(albedo_value: f32) -> f32 {
    return clamp(sanitize(albedo_value), 0.0, 1.0) + ALBEDO_EPSILON;
}
