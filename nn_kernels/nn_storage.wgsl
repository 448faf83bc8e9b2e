// Element type of activation tensors and the sanitizer every kernel applies before a store.
// Activations live in NC4HW4 layout: channel block b (4 channels) of a tensor is an H×W plane of
// vec4<T>. T is f32 or f16 ({{STORAGE}}); math happens in f32 and values are clamped to T's finite
// range with NaN mapped to 0, so no NaN or Inf is ever stored.
alias T = {{STORAGE}};
const STORAGE_MAX: f32 = {{STORAGE_MAX}};

fn finite_or_zero(v: vec4f) -> vec4f {
    let magnitude_bits = bitcast<vec4u>(v) & vec4u(0x7fffffffu);
    let is_nan = magnitude_bits > vec4u(0x7f800000u);
    return select(clamp(v, vec4f(-STORAGE_MAX), vec4f(STORAGE_MAX)), vec4f(0.0), is_nan);
}

fn to_storage(v: vec4f) -> vec4<T> {
    return vec4<T>(finite_or_zero(v));
}
