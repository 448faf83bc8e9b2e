// Isotropic GGX (Trowbridge-Reitz) microfacet distribution with the separable Smith shadowing term
// and Heitz's (2018) sampling of the distribution of visible normals, in the local shading frame
// (z = normal). Shared by the rough conductor and the rough dielectric.

// #import math.wgsl

fn ggx_d(m: vec3f, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let c2 = m.z * m.z;
    let denom = c2 * (a2 - 1.0) + 1.0;
    return select(0.0, a2 / (PI * denom * denom), m.z > 0.0);
}

fn ggx_g1(v: vec3f, m: vec3f, alpha: f32) -> f32 {
    let xy = alpha * alpha * (v.x * v.x + v.y * v.y);
    let tan2 = xy / (v.z * v.z);
    let g = select(2.0 / (1.0 + sqrt(1.0 + tan2)), 1.0, xy == 0.0);
    return select(g, 0.0, dot(v, m) * v.z <= 0.0);
}

// A microfacet normal distributed as D_v(m) = G1(v, m)·max(0, v·m)·D(m) / v.z; v must have v.z > 0.
fn ggx_sample_visible(v: vec3f, alpha: f32, u: vec2f) -> vec3f {
    let vh = normalize(vec3f(alpha * v.x, alpha * v.y, v.z));
    let lensq = vh.x * vh.x + vh.y * vh.y;
    let t1 = select(vec3f(1.0, 0.0, 0.0), vec3f(-vh.y, vh.x, 0.0) * inverseSqrt(lensq), lensq > 0.0);
    let t2 = cross(vh, t1);
    let r = sqrt(u.x);
    let phi = 2.0 * PI * u.y;
    let p1 = r * cos(phi);
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * sqrt(max(0.0, 1.0 - p1 * p1)) + s * r * sin(phi);
    let nh = p1 * t1 + p2 * t2 + sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2)) * vh;
    return normalize(vec3f(alpha * nh.x, alpha * nh.y, max(1e-6, nh.z)));
}

// pdf of ggx_sample_visible producing m (v.z > 0).
fn ggx_visible_pdf(v: vec3f, m: vec3f, alpha: f32) -> f32 {
    return ggx_g1(v, m, alpha) * abs(dot(v, m)) * ggx_d(m, alpha) / abs(v.z);
}
