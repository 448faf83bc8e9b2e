// Display transform, one invocation per pixel: sanitise (NaN/Inf/negative → 0), scale by the exposure
// (2^EXPOSURE stops), tone-map (OPERATOR 0: none, 1: Reinhard x/(1+x) per channel, 2: ACES fitted,
// Stephen Hill's fit of the RRT+ODT: sRGB → ACES-ish input matrix, rational curve, output matrix,
// saturate), encode with the sRGB OETF when SRGB, then write either one packed RGBA8 u32 per pixel
// (to_rgba8: pack4x8unorm rounds to nearest, alpha 255) or four planar f32 planes RGBA (to_rgba32f; the
// values are not clamped when OPERATOR is 0 and SRGB is off, so linear HDR survives for EXR output).
// #import frame/common.wgsl

override OPERATOR: u32 = 0u;
override EXPOSURE: f32 = 0.0;   // stops, within ±wgpu_rt.frame.tonemap.MAX_EXPOSURE_STOPS: 2^EXPOSURE is normal
override SRGB: bool = true;

// Reinhard's input is clamped here, where the curve has long been 1 in f32: WGSL guarantees a quotient
// only for divisors up to 2^126, and NVIDIA divides by multiplying with a reciprocal that flushes to
// zero beyond it (x/(1+x) at 3e38 gave 0). == wgpu_rt.frame.tonemap.CURVE_INPUT_MAX.
const CURVE_INPUT_MAX: f32 = 1.0e30;

@group(0) @binding(0) var<storage, read> color: array<f32>;
@group(0) @binding(1) var<storage, read_write> display: array<u32>;   // u32 RGBA8 or f32 bit patterns

fn aces_fitted(linear: vec3f) -> vec3f {
    // The curve is flat (→ 1/0.983729) long before 1e6; clamping there keeps v·v finite and the
    // divisor below 2^126 (see CURVE_INPUT_MAX).
    let v = min(vec3f(dot(vec3f(0.59719, 0.35458, 0.04823), linear),
                  dot(vec3f(0.07600, 0.90834, 0.01566), linear),
                  dot(vec3f(0.02840, 0.13383, 0.83777), linear)), vec3f(1.0e6));
    let curve = (v * (v + 0.0245786) - 0.000090537) / (v * (0.983729 * v + 0.4329510) + 0.238081);
    return clamp(vec3f(dot(vec3f(1.60475, -0.53108, -0.07367), curve),
                       dot(vec3f(-0.10208, 1.10813, -0.00605), curve),
                       dot(vec3f(-0.00327, -0.07276, 1.07602), curve)), vec3f(0.0), vec3f(1.0));
}

fn srgb_oetf(v: vec3f) -> vec3f {
    let x = max(v, vec3f(0.0));
    return select(1.055 * pow(x, vec3f(1.0 / 2.4)) - 0.055, 12.92 * x, x <= vec3f(0.0031308));
}

fn display_color(i: u32) -> vec3f {
    let n = pixel_count();
    var v = vec3f(sanitize(color[i]), sanitize(color[n + i]), sanitize(color[2u * n + i]));
    v = min(v * exp2(EXPOSURE), vec3f(3.0e38));
    if (OPERATOR == 1u) { v = min(v, vec3f(CURVE_INPUT_MAX)); v = v / (1.0 + v); }
    if (OPERATOR == 2u) { v = aces_fitted(v); }
    if (SRGB) { v = srgb_oetf(v); }
    return v;
}

@compute @workgroup_size(8, 8)
fn to_rgba8(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    display[i] = pack4x8unorm(vec4f(display_color(i), 1.0));
}

@compute @workgroup_size(8, 8)
fn to_rgba32f(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    let n = pixel_count();
    let v = display_color(i);
    display[i] = bitcast<u32>(v.r);
    display[n + i] = bitcast<u32>(v.g);
    display[2u * n + i] = bitcast<u32>(v.b);
    display[3u * n + i] = bitcast<u32>(1.0);
}
