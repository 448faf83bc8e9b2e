// Deterministic low-discrepancy sampling: Owen-scrambled Sobol points with hash-based scrambling
// (Burley 2020, "Practical Hash-based Owen Scrambling"). Each pixel walks the same Sobol sequence, but
// every dimension group shuffles the sample index with a nested-uniform scramble keyed by
// (pixel, seed, dimension) and scrambles the point's bits the same way, so pixels and dimensions are
// decorrelated while every power-of-two prefix of a pixel's samples stays stratified. Identical inputs
// give identical bits, which is what makes a render reproducible from its seed.

// #import math.wgsl

struct Sampler {
    index: u32,      // the sample's index in its pixel's sequence
    key: u32,        // hash of (pixel, seed): the per-pixel decorrelation key
    dimension: u32,  // next dimension group to hand out
}

// A 32-bit integer hash with good avalanche (Wellons' "lowbias32").
fn hash_u32(value: u32) -> u32 {
    var x = value;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    x ^= x >> 16u;
    return x;
}

fn hash_combine(a: u32, b: u32) -> u32 {
    return hash_u32(a ^ (b + 0x9e3779b9u + (a << 6u) + (a >> 2u)));
}

// Laine-Karras style permutation: flips each bit as a hash of the bits below it (in reversed order,
// i.e. of the more significant bits of the original value), an Owen scramble in base 2.
fn laine_karras_permutation(value: u32, seed: u32) -> u32 {
    var x = value + seed;
    x ^= x * 0x6c50b47cu;
    x ^= x * 0xb82f1e52u;
    x ^= x * 0xc7afe638u;
    x ^= x * 0x8d22f6e6u;
    return x;
}

fn nested_uniform_scramble(value: u32, seed: u32) -> u32 {
    return reverseBits(laine_karras_permutation(reverseBits(value), seed));
}

// Sobol dimension 1 (primitive polynomial x + 1); dimension 0 is the bit reversal of the index. Its
// generator matrix is Pascal's triangle mod 2 (Lucas: output bit j takes index bit k iff k ⊇ j as bit
// sets), so the product is an XOR over supersets, done for all 32 bits in five shift-XOR stages and
// then bit-reversed: no loop (loops cost a pass each on SIMD drivers and count toward lavapipe's cap).
fn sobol_dimension1(index: u32) -> u32 {
    var y = index;
    y ^= (y >> 1u) & 0x55555555u;
    y ^= (y >> 2u) & 0x33333333u;
    y ^= (y >> 4u) & 0x0f0f0f0fu;
    y ^= (y >> 8u) & 0x00ff00ffu;
    y ^= (y >> 16u) & 0x0000ffffu;
    return reverseBits(y);
}

fn u32_to_unit_float(bits: u32) -> f32 {
    // the top 24 bits, so the result is exactly representable and strictly below 1
    return f32(bits >> 8u) * (1.0 / 16777216.0);
}

fn sampler_start(pixel: u32, sample_index: u32, seed: u32) -> Sampler {
    return Sampler(sample_index, hash_combine(hash_u32(pixel), seed), 0u);
}

fn sampler_group_seed(s: ptr<function, Sampler>) -> u32 {
    let seed = hash_combine((*s).key, (*s).dimension);
    (*s).dimension += 1u;
    return seed;
}

fn next_1d(s: ptr<function, Sampler>) -> f32 {
    let seed = sampler_group_seed(s);
    let shuffled = nested_uniform_scramble((*s).index, seed);
    return u32_to_unit_float(nested_uniform_scramble(reverseBits(shuffled), hash_u32(seed)));
}

fn next_2d(s: ptr<function, Sampler>) -> vec2f {
    let seed = sampler_group_seed(s);
    let shuffled = nested_uniform_scramble((*s).index, seed);
    let x = nested_uniform_scramble(reverseBits(shuffled), hash_u32(seed ^ 0x5bd1e995u));
    let y = nested_uniform_scramble(sobol_dimension1(shuffled), hash_u32(seed ^ 0x1b873593u));
    return vec2f(u32_to_unit_float(x), u32_to_unit_float(y));
}

// -- warps from the unit square ---------------------------------------------------------------------

// A point uniform over the unit disc: the concentric mapping (Shirley-Chiu), which keeps strata compact.
fn square_to_uniform_disk(u: vec2f) -> vec2f {
    let p = 2.0 * u - 1.0;
    var r: f32;
    var phi: f32;
    if p.x == 0.0 && p.y == 0.0 {
        return vec2f(0.0);
    }
    if abs(p.x) > abs(p.y) {
        r = p.x;
        phi = (PI / 4.0) * (p.y / p.x);
    } else {
        r = p.y;
        phi = (PI / 2.0) - (PI / 4.0) * (p.x / p.y);
    }
    return r * vec2f(cos(phi), sin(phi));
}

fn square_to_cosine_hemisphere(u: vec2f) -> vec3f {
    // the uniform disc lifted to the hemisphere
    let d = square_to_uniform_disk(u);
    return vec3f(d, sqrt(max(0.0, 1.0 - dot(d, d))));
}

fn square_to_uniform_sphere(u: vec2f) -> vec3f {
    let z = 1.0 - 2.0 * u.y;
    let r = sqrt(max(0.0, 1.0 - z * z));
    let phi = 2.0 * PI * u.x;
    return vec3f(r * cos(phi), r * sin(phi), z);
}

// Barycentrics (b1, b2) uniform over a triangle (the square-root parameterization).
fn square_to_triangle(u: vec2f) -> vec2f {
    let su = sqrt(u.x);
    return vec2f(1.0 - su, u.y * su);
}
