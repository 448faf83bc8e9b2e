// The denoised frame's low band taken from a second denoiser pass at half resolution
// (wgpu_rt/frame/lowband.py says why and when). With F the full-resolution denoised radiance, H the
// half-resolution one (4× the samples per pixel, twice the network's reach), LF and LH their means over
// 4×4 frame pixels (quarter resolution) and w the mean of 1/spp over the same pixels:
//   out = F · (w·LH + (1 − w)·LF + ε) / (LF + ε),   LF, LH and w bilinear between quarter-pixel centres,
// so the detail above the quarter band is F's own and the band below it moves towards H by w (a low-band
// weight too: an adaptive sample map does not print its pixels into the correction).
//   low_band_means: one invocation per quarter pixel → `means`, 7 planes: LF (3), LH (3), w
//   low_band_apply: one invocation per frame pixel, `denoised` rewritten in place
// #import frame/common.wgsl
// #import frame/albedo.wgsl

override EPSILON: f32;                  // radiance added to both low bands (LOW_BAND_EPSILON)
const MAX_LOG_RADIANCE: f32 = 88.0;     // as frame/unpack.wgsl

@group(0) @binding(0) var<storage, read_write> denoised: array<f32>;   // F, 3 planes of the frame
@group(0) @binding(1) var<storage, read> half_output: array<f32>;      // the network at half resolution
@group(0) @binding(2) var<storage, read> half_input: array<f32>;       // pack_denoiser_half's 11 planes
@group(0) @binding(3) var<storage, read_write> means: array<f32>;
@group(0) @binding(4) var<storage, read> spp: array<u32>;

fn half_size() -> vec2u { return vec2u((WIDTH + 1u) / 2u, (HEIGHT + 1u) / 2u); }

fn quarter_size() -> vec2u { return vec2u((WIDTH + 3u) / 4u, (HEIGHT + 3u) / 4u); }

// H at half pixel (x, y) on channel c: the network's output unpacked as frame/unpack.wgsl does, by the
// half-resolution albedo that pack_denoiser_half packed (planes 3–5 of its input).
fn half_radiance(c: u32, x: u32, y: u32) -> f32 {
    let n = half_size().x * half_size().y;
    let i = y * half_size().x + x;
    let log_irradiance = clamp(finite_or_zero(half_output[c * n + i]), 0.0, MAX_LOG_RADIANCE);
    return expm1_accurate(log_irradiance) * albedo_factor(half_input[(3u + c) * n + i]);
}

@compute @workgroup_size(8, 8)
fn low_band_means(@builtin(global_invocation_id) id: vec3u) {
    let quarter = quarter_size();
    if (id.x >= quarter.x || id.y >= quarter.y) { return; }
    let n = pixel_count();
    let first = 4u * id.xy;
    let last = min(first + 4u, vec2u(WIDTH, HEIGHT));
    let share = 1.0 / f32((last.x - first.x) * (last.y - first.y));   // per frame pixel of the block
    var low_full = vec3f(0.0);
    var weight_mean = 0.0;
    for (var y = first.y; y < last.y; y++) {
        for (var x = first.x; x < last.x; x++) {
            for (var c = 0u; c < 3u; c++) { low_full[c] += denoised[c * n + y * WIDTH + x] * share; }
            weight_mean += share / f32(max(spp[y * WIDTH + x], 1u));
        }
    }
    // The half pixels of the block, each weighed by the frame pixels it covers (fewer at an odd edge).
    var low_half = vec3f(0.0);
    let half_last = min(2u * id.xy + 2u, half_size());
    for (var y = 2u * id.y; y < half_last.y; y++) {
        for (var x = 2u * id.x; x < half_last.x; x++) {
            let covered = min(2u * vec2u(x, y) + 2u, vec2u(WIDTH, HEIGHT)) - 2u * vec2u(x, y);
            let weight = f32(covered.x * covered.y) * share;
            for (var c = 0u; c < 3u; c++) { low_half[c] += half_radiance(c, x, y) * weight; }
        }
    }
    let m = quarter.x * quarter.y;
    let q = id.y * quarter.x + id.x;
    for (var c = 0u; c < 3u; c++) {
        means[c * m + q] = min(low_full[c], F32_MAX);
        means[(3u + c) * m + q] = min(low_half[c], F32_MAX);
    }
    means[6u * m + q] = weight_mean;
}

// Bilinear weights between quarter-pixel centres along one axis: (first index, second index, t).
fn quarter_axis(position: u32, count: u32) -> vec3f {
    let u = clamp((f32(position) + 0.5) * 0.25 - 0.5, 0.0, f32(count - 1u));
    let first = floor(u);
    return vec3f(first, min(first + 1.0, f32(count - 1u)), u - first);
}

fn bilinear(plane: u32, ax: vec3f, ay: vec3f) -> f32 {
    let quarter = quarter_size();
    let base = plane * quarter.x * quarter.y;
    let row0 = base + u32(ay.x) * quarter.x;
    let row1 = base + u32(ay.y) * quarter.x;
    let top = mix(means[row0 + u32(ax.x)], means[row0 + u32(ax.y)], ax.z);
    let bottom = mix(means[row1 + u32(ax.x)], means[row1 + u32(ax.y)], ax.z);
    return mix(top, bottom, ay.z);
}

@compute @workgroup_size(8, 8)
fn low_band_apply(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    let n = pixel_count();
    let ax = quarter_axis(id.x, quarter_size().x);
    let ay = quarter_axis(id.y, quarter_size().y);
    let w = bilinear(6u, ax, ay);
    for (var c = 0u; c < 3u; c++) {
        let low_full = bilinear(c, ax, ay);
        let low_half = bilinear(3u + c, ax, ay);
        let ratio = min((w * low_half + (1.0 - w) * low_full + EPSILON) / (low_full + EPSILON), F32_MAX);
        denoised[c * n + i] = min(denoised[c * n + i] * ratio, F32_MAX);
    }
}
