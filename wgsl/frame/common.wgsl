// Shared by the frame passes: the frame size (pipeline override constants), the 8×8 pixel tiling and
// the sanitising rule. A value is finite when its exponent bits are not all ones; this is tested on the
// bit pattern because a compiler may fold `x != x` away under fast-math assumptions.

override WIDTH: u32;
override HEIGHT: u32;
const TILE: u32 = 8u;
const F32_MAX: f32 = 3.4028234e38;   // the largest finite f32 (rounded to it)

fn pixel_count() -> u32 { return WIDTH * HEIGHT; }

fn in_frame(id: vec3u) -> bool { return id.x < WIDTH && id.y < HEIGHT; }

fn pixel_index(id: vec3u) -> u32 { return id.y * WIDTH + id.x; }

fn is_finite(x: f32) -> bool { return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u; }

// NaN/±Inf → 0, sign kept (normals).
fn finite_or_zero(x: f32) -> f32 { return select(0.0, x, is_finite(x)); }

// NaN/±Inf → 0, negatives → 0 (radiance, albedo, depth): a failed sample contributes nothing.
fn sanitize(x: f32) -> f32 { return max(finite_or_zero(x), 0.0); }

// a / b for any finite b: WGSL promises a quotient only for |b| up to 2^126, and NVIDIA divides by
// multiplying with 1/b, which beyond that is subnormal and flushed to 0 (3e38 / 3e38 gave 0). Such a b
// and its a are scaled by 2^-64 first.
fn quotient(a: f32, b: f32) -> f32 {
    let scale = select(1.0, 5.4210108624275222e-20, abs(b) > 8.5070591730234616e37);   // 2^-64, 2^126
    return (a * scale) / (b * scale);
}

// log(1 + x) for x ≥ 0, accurate near 0 (Goldberg's trick: the rounding error of 1 + x cancels).
fn log1p_accurate(x: f32) -> f32 {
    let u = 1.0 + x;
    if (u == 1.0) { return x; }
    return log(u) * (x / (u - 1.0));
}

// exp(x) − 1, accurate near 0 (Kahan's trick).
fn expm1_accurate(x: f32) -> f32 {
    let u = exp(x);
    if (u == 1.0) { return x; }
    let um1 = u - 1.0;
    if (um1 == -1.0) { return -1.0; }
    return um1 * (x / log(u));
}
