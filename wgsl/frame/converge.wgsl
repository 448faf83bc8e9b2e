// The denoised frame of an n-sample mean, blended with that mean per pixel by how far each can be
// trusted, measured in the pixel's neighbourhood (RADIUS; the window shrinks at the image's edges).
// The mean's error comes from a copy of it taken after its first h samples (the half planes):
// the two parts' means differ by m_h − m_rest, so σ² ≈ (m − m_h)² · h / (n − h) estimates the
// variance of the n-sample mean (exact in expectation for independent samples; for the tracer's
// stratified sequence both parts are stratified alike, so it follows the error the sequence really
// has, where the samples' own spread would overstate it). Then, averaged over the window, each
// pixel's squared differences weighed by q, the squared slope of the display transform
// (x / (1 + x))^(1/2.2) at its denoised value (a dark pixel's error counts as it shows on screen, not
// by its small linear size; display_slope2 in the reference) and each neighbour j by how alike it looks
// to the centre i, exp(−(v_j − v_i)² / 2 TAU²) of their denoised display values v (so one bright pixel
// whose two parts disagree, a caustic, does not make its whole window keep the denoised frame; the
// averages divide by the sum of these weights),
//   D² = the squared difference between denoised frame and mean,
//   e² = max(D² − σ², 0): the denoiser's own squared error (D² ≈ e² + σ² when the errors are independent),
//   out = mix(denoised, mean, w), w = min(e² / (e² + σ²), n² / (n² + CAP_SCALE)),
// per channel: inverse-variance weights, so a converged mean takes over where the denoiser is biased,
// while one whose parts disagree (a firefly) leaves the denoised value. The cap keeps the mean out at
// a few spp, where an estimate from so few samples cannot be trusted. Only pixels with samples after
// the copy (n > h) have an estimate: the window's averages leave the others out, and such a pixel
// keeps its denoised value. Fitted with benchmarks/bench_converge.py, refitted at 256² (wgpu_rt/frame/converge.py).
// Each 8×4 workgroup first works out, once per pixel of its tile and the tile's RADIUS-wide halo, what
// the window sums need (display value, weighed squared split and difference, whether it took samples
// after the copy) in workgroup memory; the windows then read only that. The tile is 8×4, not the frame
// passes' 8×8, so that with its halo it fits WebGPU's default 16 KiB of workgroup memory (15,840 bytes).
// #import frame/common.wgsl

const RADIUS: i32 = 7;                          // CONVERGE_RADIUS in wgpu_rt/frame/converge.py
const TILE_X: u32 = 8u;                         // CONVERGE_TILE in wgpu_rt/frame/converge.py
const TILE_Y: u32 = 4u;
const SPAN_X: u32 = TILE_X + 2u * u32(RADIUS);  // the tile and its halo
const SPAN_Y: u32 = TILE_Y + 2u * u32(RADIUS);
override CAP_SCALE: f32 = 384.0;
override TAU: f32 = 0.05;
override SLOPE_GAMMA: f32 = 2.2;
override SLOPE_FLOOR: f32 = 1e-4;

@group(0) @binding(0) var<storage, read> denoised: array<f32>;
@group(0) @binding(1) var<storage, read> samples_mean: array<f32>;
@group(0) @binding(2) var<storage, read> spp: array<u32>;
@group(0) @binding(3) var<storage, read> half_mean: array<f32>;
@group(0) @binding(4) var<storage, read> half_spp: array<u32>;
@group(0) @binding(5) var<storage, read_write> converged: array<f32>;

// Per pixel of the tile and halo, nine floats: per channel the display value of the denoised frame
// (offset VALUE), the weighed squared split of the mean (its variance term, VARIANCE) and the squared
// difference denoised − mean (DIFFERENCE); flat floats, since a vec3f's stride is 16 bytes. And 1 where the
// pixel is in the frame and took samples after the copy, else 0.
const VALUE: u32 = 0u;
const VARIANCE: u32 = 3u;
const DIFFERENCE: u32 = 6u;
var<workgroup> tile: array<f32, 9u * SPAN_X * SPAN_Y>;
var<workgroup> tile_estimated: array<f32, SPAN_X * SPAN_Y>;

fn tile_vec3(k: u32, offset: u32) -> vec3f {
    let at = 9u * k + offset;
    return vec3f(tile[at], tile[at + 1u], tile[at + 2u]);
}

// (x / (1 + x))^(1/γ) of x ≥ 0: the display value.
fn display_value(x: f32) -> f32 {
    return pow(x / (1.0 + x), 1.0 / SLOPE_GAMMA);
}

// Squared derivative of (x / (1 + x))^(1/γ) at max(x, SLOPE_FLOOR), from ``shown``, the display value
// of x already worked out: the derivative is that value / (γ x (1 + x)), so no second pow per channel.
fn display_slope2(value: f32, shown: f32) -> f32 {
    let x = max(value, SLOPE_FLOOR);
    let slope = select(shown, display_value(SLOPE_FLOOR), value < SLOPE_FLOOR) / (SLOPE_GAMMA * x * (1.0 + x));
    return slope * slope;
}

fn load_tile_pixel(k: u32, origin: vec2i) {
    let n = pixel_count();
    let p = origin + vec2i(i32(k % SPAN_X), i32(k / SPAN_X));
    var value = vec3f(0.0);
    var variance = vec3f(0.0);
    var difference = vec3f(0.0);
    var estimated = 0.0;
    if (all(p >= vec2i(0)) && p.x < i32(WIDTH) && p.y < i32(HEIGHT)) {
        let j = u32(p.y) * WIDTH + u32(p.x);
        let first = half_spp[j];
        let later = spp[j] > first;
        estimated = select(0.0, 1.0, later);
        for (var c = 0u; c < 3u; c++) {
            let denoised_value = sanitize(denoised[c * n + j]);
            value[c] = display_value(denoised_value);
            if (later) {
                let mean = sanitize(samples_mean[c * n + j]);
                let split = mean - sanitize(half_mean[c * n + j]);
                let q = display_slope2(denoised_value, value[c]);
                variance[c] = q * (split * split * f32(first) / f32(spp[j] - first));
                let d = denoised_value - mean;
                difference[c] = q * (d * d);
            }
        }
    }
    for (var c = 0u; c < 3u; c++) {
        tile[9u * k + VALUE + c] = value[c];
        tile[9u * k + VARIANCE + c] = variance[c];
        tile[9u * k + DIFFERENCE + c] = difference[c];
    }
    tile_estimated[k] = estimated;
}

@compute @workgroup_size(8, 4)
fn main(@builtin(global_invocation_id) id: vec3u, @builtin(local_invocation_id) local: vec3u,
        @builtin(local_invocation_index) local_index: u32, @builtin(workgroup_id) group: vec3u) {
    let origin = vec2i(group.xy * vec2u(TILE_X, TILE_Y)) - RADIUS;
    for (var k = local_index; k < SPAN_X * SPAN_Y; k += TILE_X * TILE_Y) { load_tile_pixel(k, origin); }
    workgroupBarrier();
    if (!in_frame(id)) { return; }
    let n = pixel_count();
    let i = pixel_index(id);
    let centre = tile_vec3((local.y + u32(RADIUS)) * SPAN_X + local.x + u32(RADIUS), VALUE);
    var variance = vec3f(0.0);
    var difference = vec3f(0.0);
    var window = vec3f(0.0);
    for (var y = 0u; y <= 2u * u32(RADIUS); y++) {
        for (var x = 0u; x <= 2u * u32(RADIUS); x++) {
            let k = (local.y + y) * SPAN_X + local.x + x;
            let alike = tile_vec3(k, VALUE) - centre;
            let w = tile_estimated[k] * exp(-alike * alike / (2.0 * TAU * TAU));
            window += w;
            variance += w * tile_vec3(k, VARIANCE);
            difference += w * tile_vec3(k, DIFFERENCE);
        }
    }
    let estimated = spp[i] > half_spp[i];
    let samples = f32(max(spp[i], 1u));
    let cap = samples * samples / (samples * samples + CAP_SCALE);
    for (var c = 0u; c < 3u; c++) {
        let sigma2 = variance[c] / max(window[c], 1.0);
        let error2 = max(difference[c] / max(window[c], 1.0) - sigma2, 0.0);
        var weight = cap;
        if (error2 + sigma2 > 0.0) { weight = min(error2 / (error2 + sigma2), cap); }
        // overflowed sums (inf − inf, inf / inf) must not reach the image: the denoised value stands
        if (!estimated || !is_finite(sigma2) || !is_finite(error2) || !is_finite(weight)) { weight = 0.0; }
        let d = sanitize(denoised[c * n + i]);
        converged[c * n + i] = d + weight * (sanitize(samples_mean[c * n + i]) - d);
    }
}
