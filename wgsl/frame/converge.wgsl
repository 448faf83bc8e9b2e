// The denoised frame of an n-sample mean, blended with that mean per pixel by how far each can be
// trusted, measured in the pixel's neighbourhood (RADIUS; the window shrinks at the image's edges).
// The mean's error comes from a copy of it taken after its first h samples (the half planes):
// the two parts' means differ by m_h − m_rest, so σ² ≈ (m − m_h)² · h / (n − h) estimates the
// variance of the n-sample mean (exact in expectation for independent samples; for the tracer's
// stratified sequence both parts are stratified alike, so it follows the error the sequence really
// has, where the samples' own spread would overstate it). Then, averaged over the window, each
// pixel's squared differences weighed by q, the squared slope of the display transform
// (x / (1 + x))^(1/2.2) at its denoised value (a dark pixel's error counts as it shows on screen, not
// by its small linear size; display_slope2 in the reference),
//   D² = the squared difference between denoised frame and mean,
//   e² = max(D² − σ², 0): the denoiser's own squared error (D² ≈ e² + σ² when the errors are independent),
//   out = mix(denoised, mean, w), w = min(e² / (e² + σ²), n² / (n² + CAP_SCALE)),
// per channel: inverse-variance weights, so a converged mean takes over where the denoiser is biased,
// while one whose parts disagree (a firefly) leaves the denoised value. The cap keeps the mean out at
// a few spp, where an estimate from so few samples cannot be trusted. Only pixels with samples after
// the copy (n > h) have an estimate: the window's averages leave the others out, and such a pixel
// keeps its denoised value. Fitted with benchmarks/bench_converge.py (wgpu_rt/frame/converge.py).
// #import frame/common.wgsl

override RADIUS: i32 = 2;
override CAP_SCALE: f32 = 1024.0;
override SLOPE_GAMMA: f32 = 2.2;
override SLOPE_FLOOR: f32 = 1e-4;

@group(0) @binding(0) var<storage, read> denoised: array<f32>;
@group(0) @binding(1) var<storage, read> samples_mean: array<f32>;
@group(0) @binding(2) var<storage, read> spp: array<u32>;
@group(0) @binding(3) var<storage, read> half_mean: array<f32>;
@group(0) @binding(4) var<storage, read> half_spp: array<u32>;
@group(0) @binding(5) var<storage, read_write> converged: array<f32>;

// Squared derivative of (x / (1 + x))^(1/γ) at max(x, SLOPE_FLOOR).
fn display_slope2(value: f32) -> f32 {
    let x = max(value, SLOPE_FLOOR);
    let slope = pow(x / (1.0 + x), 1.0 / SLOPE_GAMMA - 1.0) / (SLOPE_GAMMA * (1.0 + x) * (1.0 + x));
    return slope * slope;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let n = pixel_count();
    let i = pixel_index(id);
    let low = max(vec2i(id.xy) - RADIUS, vec2i(0));
    let high = min(vec2i(id.xy) + RADIUS, vec2i(i32(WIDTH), i32(HEIGHT)) - 1);
    var variance = vec3f(0.0);
    var difference = vec3f(0.0);
    var window = 0.0;
    for (var y = low.y; y <= high.y; y++) {
        for (var x = low.x; x <= high.x; x++) {
            let j = u32(y) * WIDTH + u32(x);
            let first = half_spp[j];
            if (spp[j] <= first) { continue; }
            window += 1.0;
            for (var c = 0u; c < 3u; c++) {
                let mean = sanitize(samples_mean[c * n + j]);
                let split = mean - sanitize(half_mean[c * n + j]);
                let value = sanitize(denoised[c * n + j]);
                let q = display_slope2(value);
                variance[c] += q * (split * split * f32(first) / f32(spp[j] - first));
                let d = value - mean;
                difference[c] += q * (d * d);
            }
        }
    }
    let estimated = spp[i] > half_spp[i];
    let samples = f32(max(spp[i], 1u));
    let cap = samples * samples / (samples * samples + CAP_SCALE);
    for (var c = 0u; c < 3u; c++) {
        let sigma2 = variance[c] / max(window, 1.0);
        let error2 = max(difference[c] / max(window, 1.0) - sigma2, 0.0);
        var weight = cap;
        if (error2 + sigma2 > 0.0) { weight = min(error2 / (error2 + sigma2), cap); }
        // overflowed sums (inf − inf, inf / inf) must not reach the image: the denoised value stands
        if (!estimated || !is_finite(sigma2) || !is_finite(error2) || !is_finite(weight)) { weight = 0.0; }
        let d = sanitize(denoised[c * n + i]);
        converged[c * n + i] = d + weight * (sanitize(samples_mean[c * n + i]) - d);
    }
}
