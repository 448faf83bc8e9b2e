// The denoised frame's chromaticity held to its samples' block means (wgpu_rt/frame/chroma.py says why
// and is the reference): over BLOCK×BLOCK-pixel blocks (frame/block_grid.wgsl),
//   chroma_statistics: one invocation per block → `statistics`, 9 planes: the means of the denoised
//                      radiance F (3) and of the samples' mean N (3), and the variance of N's block mean
//                      (3): the spread of r = N − F about its block mean, Σ(r − r̄)² / (n (n − 1))
//   chroma_ratios:     one invocation per block → `ratios`, 3 planes: the Gaussian-weighted means over the
//                      (2·RADIUS + 1)² blocks around it (indices clamped; the variance weighed by the
//                      squared weights), F's mean moved towards N's by k = max(0, 1 − var / (N̄ − F̄)²) per
//                      channel, and each channel's share of the three (ε added: SHARE_EPSILON times how
//                      much brighter than pack.py's STEPS_KEY the frame is, so that it scales with the
//                      frame's light) in the result over its share in F's mean, clamped to
//                      [1/RATIO_LIMIT, RATIO_LIMIT]
//   chroma_apply:      one invocation per pixel: F scaled by the ratios, bilinear between block centres
// #import frame/common.wgsl
// #import frame/block_grid.wgsl

override SHARE_EPSILON: f32;      // radiance added to each channel's mean before taking shares
override RATIO_LIMIT: f32;
override KEY_RATIO: f32;          // pack.py's: exposure[3] · KEY_RATIO is the frame's key over STEPS_KEY
override STATISTICS_LIMIT: f32;   // radiance clamped to this for the statistics (squares stay finite)
override TAP_0: f32;              // the normalised Gaussian's weights at offsets 0 … RADIUS blocks
override TAP_1: f32;              // (chroma.gaussian_taps)
override TAP_2: f32;
override TAP_3: f32;
const RADIUS: i32 = 3;            // chroma.RADIUS_BLOCKS

@group(0) @binding(0) var<storage, read> color: array<f32>;              // N, 3 planes
@group(0) @binding(1) var<storage, read_write> denoised: array<f32>;     // F, 3 planes, rewritten
@group(0) @binding(2) var<storage, read_write> statistics: array<f32>;
@group(0) @binding(3) var<storage, read_write> ratios: array<f32>;
@group(0) @binding(4) var<storage, read> exposure: array<f32, 4>;      // [3]: the frame's (frame/balance.wgsl)

fn statistic(x: f32) -> f32 { return min(sanitize(x), STATISTICS_LIMIT); }

@compute @workgroup_size(8, 8)
fn chroma_statistics(@builtin(global_invocation_id) id: vec3u) {
    let blocks = block_count();
    if (id.x >= blocks.x || id.y >= blocks.y) { return; }
    let n = pixel_count();
    let first = block_first(id.xy);
    let last = block_last(id.xy);
    let pixels = f32((last.x - first.x) * (last.y - first.y));
    var sum_f = vec3f(0.0);
    var sum_n = vec3f(0.0);
    for (var y = first.y; y < last.y; y++) {
        for (var x = first.x; x < last.x; x++) {
            let i = y * WIDTH + x;
            for (var c = 0u; c < 3u; c++) {
                sum_f[c] += statistic(denoised[c * n + i]);
                sum_n[c] += statistic(color[c * n + i]);
            }
        }
    }
    let mean_f = sum_f / pixels;
    let mean_n = sum_n / pixels;
    // The residual r = N − F about its block mean (that mean is the bias sought, not noise).
    var spread = vec3f(0.0);
    for (var y = first.y; y < last.y; y++) {
        for (var x = first.x; x < last.x; x++) {
            let i = y * WIDTH + x;
            for (var c = 0u; c < 3u; c++) {
                let r = statistic(color[c * n + i]) - statistic(denoised[c * n + i]) - (mean_n[c] - mean_f[c]);
                spread[c] += r * r;
            }
        }
    }
    let m = blocks.x * blocks.y;
    let q = id.y * blocks.x + id.x;
    for (var c = 0u; c < 3u; c++) {
        statistics[c * m + q] = mean_f[c];
        statistics[(3u + c) * m + q] = mean_n[c];
        statistics[(6u + c) * m + q] = spread[c] / (pixels * max(pixels - 1.0, 1.0));
    }
}

fn tap(offset: i32) -> f32 {
    let d = abs(offset);
    return select(select(select(TAP_3, TAP_2, d == 2), TAP_1, d == 1), TAP_0, d == 0);
}

@compute @workgroup_size(8, 8)
fn chroma_ratios(@builtin(global_invocation_id) id: vec3u) {
    let blocks = block_count();
    if (id.x >= blocks.x || id.y >= blocks.y) { return; }
    let m = blocks.x * blocks.y;
    var low_f = vec3f(0.0);
    var low_n = vec3f(0.0);
    var variance = vec3f(0.0);
    for (var dy = -RADIUS; dy <= RADIUS; dy++) {
        let y = u32(clamp(i32(id.y) + dy, 0, i32(blocks.y) - 1));
        for (var dx = -RADIUS; dx <= RADIUS; dx++) {
            let x = u32(clamp(i32(id.x) + dx, 0, i32(blocks.x) - 1));
            let w = tap(dx) * tap(dy);
            let q = y * blocks.x + x;
            for (var c = 0u; c < 3u; c++) {
                low_f[c] += w * statistics[c * m + q];
                low_n[c] += w * statistics[(3u + c) * m + q];
                variance[c] += w * w * statistics[(6u + c) * m + q];
            }
        }
    }
    let difference2 = (low_n - low_f) * (low_n - low_f);
    let k = select(vec3f(0.0), 1.0 - variance / difference2, variance < difference2);
    let epsilon = SHARE_EPSILON * (exposure[3] * KEY_RATIO);
    let moved = max(low_f + k * (low_n - low_f), vec3f(0.0)) + epsilon;
    let own = low_f + epsilon;
    let ratio = clamp((moved / (moved.x + moved.y + moved.z)) / (own / (own.x + own.y + own.z)),
                      vec3f(1.0 / RATIO_LIMIT), vec3f(RATIO_LIMIT));
    let q = id.y * blocks.x + id.x;
    for (var c = 0u; c < 3u; c++) { ratios[c * m + q] = ratio[c]; }
}

@compute @workgroup_size(8, 8)
fn chroma_apply(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    let n = pixel_count();
    let m = block_count().x * block_count().y;
    let at = block_lookup(id.xy);
    for (var c = 0u; c < 3u; c++) {
        let base = c * m;
        let ratio = block_mix(at, ratios[base + at.i00], ratios[base + at.i01], ratios[base + at.i10], ratios[base + at.i11]);
        denoised[c * n + i] = min(sanitize(denoised[c * n + i]) * ratio, F32_MAX);
    }
}
