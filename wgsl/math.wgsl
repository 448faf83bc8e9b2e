// Shared constants and small vector helpers: an orthonormal frame built from one vector (Duff et al.
// 2017, branchless), luminance, and a finite-value test that does not rely on NaN comparisons (which
// WGSL lets compilers fold away).

const PI: f32 = 3.14159265358979;
const INV_PI: f32 = 0.318309886183791;
const INV_FOUR_PI: f32 = 0.0795774715459477;

struct Frame {
    s: vec3f,
    t: vec3f,
    n: vec3f,
}

fn frame_from_normal(n: vec3f) -> Frame {
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let s = vec3f(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let t = vec3f(b, sign + n.y * n.y * a, -n.y);
    return Frame(s, t, n);
}

fn to_local(f: Frame, v: vec3f) -> vec3f {
    return vec3f(dot(v, f.s), dot(v, f.t), dot(v, f.n));
}

fn to_world(f: Frame, v: vec3f) -> vec3f {
    return f.s * v.x + f.t * v.y + f.n * v.z;
}

fn luminance(c: vec3f) -> f32 {
    return dot(c, vec3f(0.212671, 0.715160, 0.072169));
}

fn is_finite_f32(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

fn is_finite_vec3(v: vec3f) -> bool {
    return is_finite_f32(v.x) && is_finite_f32(v.y) && is_finite_f32(v.z);
}

fn power_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    let a = pdf_a * pdf_a;
    let b = pdf_b * pdf_b;
    return select(0.0, a / (a + b), a > 0.0);
}
