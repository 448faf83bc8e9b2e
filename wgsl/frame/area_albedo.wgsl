// The albedo plane of a frame traced without the aux pass holds the running mean of each pixel's own
// point samples (the tracer's first non-delta hits), jagged at every edge at a few spp, where the
// denoiser was trained on the aux pass's estimate of each pixel's area mean. Two dispatches smooth it
// into such an estimate, a Gaussian of SIGMA / sqrt(spp) pixels (the pixel's own sample count) along the
// rows, then along the columns, out to ceil(3σ) pixels (at most RADIUS), indices clamped at the frame's
// edges, weights normalised; below NEGLIGIBLE pixels the pixel is its own estimate. Reference:
// wgpu_rt/frame/area_albedo.py (area_averaged_albedo).
// #import frame/common.wgsl

override SIGMA: f32 = 0.9;        // POINT_ALBEDO_SIGMA
override NEGLIGIBLE: f32 = 0.1;   // NEGLIGIBLE_SIGMA
const RADIUS: i32 = 3;            // ceil(3 · SIGMA): the reach at one sample a pixel

@group(0) @binding(0) var<storage, read> spp: array<u32>;
@group(0) @binding(1) var<storage, read> source: array<f32>;
@group(0) @binding(2) var<storage, read_write> smoothed: array<f32>;

fn albedo_at(index: u32) -> vec3f {
    let n = pixel_count();
    return vec3f(sanitize(source[index]), sanitize(source[index + n]), sanitize(source[index + 2u * n]));
}

fn blur(id: vec3u, step: vec2i) {
    if (!in_frame(id)) { return; }
    let index = pixel_index(id);
    let samples = spp[index];
    let sigma = select(0.0, SIGMA / sqrt(f32(samples)), samples > 0u);
    var value = albedo_at(index);
    if (sigma >= NEGLIGIBLE) {
        let reach = i32(ceil(3.0 * sigma));
        let last = vec2i(i32(WIDTH) - 1, i32(HEIGHT) - 1);
        var sum = vec3f(0.0);
        var total = 0.0;
        for (var k = -RADIUS; k <= RADIUS; k++) {
            if (abs(k) > reach) { continue; }
            let at = clamp(vec2i(id.xy) + k * step, vec2i(0), last);
            let weight = exp(-f32(k * k) / (2.0 * sigma * sigma));
            sum += weight * albedo_at(u32(at.y) * WIDTH + u32(at.x));
            total += weight;
        }
        value = sum / total;
    }
    let n = pixel_count();
    smoothed[index] = value.x;
    smoothed[index + n] = value.y;
    smoothed[index + 2u * n] = value.z;
}

@compute @workgroup_size(8, 8)
fn blur_rows(@builtin(global_invocation_id) id: vec3u) { blur(id, vec2i(1, 0)); }

@compute @workgroup_size(8, 8)
fn blur_columns(@builtin(global_invocation_id) id: vec3u) { blur(id, vec2i(0, 1)); }
