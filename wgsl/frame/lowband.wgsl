// One step of the denoiser's low band (wgpu_rt/frame/lowband.py says why and when): a level of the frame
// (the full frame, or one averaged 2×2, 4×4, …) takes its band below quarter resolution from the next
// coarser level, denoised on a canvas of half its size. With F the level's denoised radiance, C the
// coarser level's (upsampled by pixel replication), LF and LC their means over 4×4 pixels of the level
// and w the mean of 1/spp over the same pixels:
//   out = F · (w·LC + (1 − w)·LF + ε) / (LF + ε),   LF, LC and w bilinear between block centres (ε: EPSILON
//   times how much brighter than pack.py's STEPS_KEY the frame is),
// so the detail above the quarter band is F's own and the band below it moves towards C by w (a low-band
// weight too: an adaptive sample map does not print its pixels into the correction). WIDTH × HEIGHT is
// the level's size.
//   low_band_means: one invocation per 4×4 block → `means`, 7 planes: LF (3), LC (3), w
//   low_band_apply: one invocation per pixel of the level, `fine` rewritten in place
// #import frame/common.wgsl
// #import frame/block_grid.wgsl

override EPSILON: f32;                 // radiance added to both low bands (LOW_BAND_EPSILON) at STEPS_KEY
override KEY_RATIO: f32;               // pack.py's: exposure[3] · KEY_RATIO is the frame's key over STEPS_KEY
override SAMPLES_PLANE: u32 = 10u;     // fine_input's 1/sqrt(spp) plane: pack_denoiser's last (0: a plane of its own)

@group(0) @binding(0) var<storage, read_write> fine: array<f32>;     // F, 3 planes of the level
@group(0) @binding(1) var<storage, read> coarse: array<f32>;         // C, 3 planes at half the size
@group(0) @binding(2) var<storage, read> fine_input: array<f32>;     // the level's packed denoiser input, or its
                                                                     // 1/sqrt(spp) plane alone (a frame in bands)
@group(0) @binding(3) var<storage, read_write> means: array<f32>;
@group(0) @binding(4) var<storage, read> exposure: array<f32, 4>;    // [3]: the frame's (frame/balance.wgsl)

fn coarse_size() -> vec2u { return vec2u((WIDTH + 1u) / 2u, (HEIGHT + 1u) / 2u); }

@compute @workgroup_size(8, 8)
fn low_band_means(@builtin(global_invocation_id) id: vec3u) {
    let blocks = block_count();
    if (id.x >= blocks.x || id.y >= blocks.y) { return; }
    let n = pixel_count();
    let first = block_first(id.xy);
    let last = block_last(id.xy);
    let share = 1.0 / f32((last.x - first.x) * (last.y - first.y));   // per pixel of the block
    var low_fine = vec3f(0.0);
    var weight_mean = 0.0;
    for (var y = first.y; y < last.y; y++) {
        for (var x = first.x; x < last.x; x++) {
            let i = y * WIDTH + x;
            for (var c = 0u; c < 3u; c++) { low_fine[c] += fine[c * n + i] * share; }
            let inverse_sqrt_spp = fine_input[SAMPLES_PLANE * n + i];
            weight_mean += inverse_sqrt_spp * inverse_sqrt_spp * share;
        }
    }
    // The coarse pixels of the block, each weighed by the level's pixels it covers (fewer at an odd edge).
    var low_coarse = vec3f(0.0);
    let half = coarse_size();
    let coarse_last = min(2u * id.xy + 2u, half);
    for (var y = 2u * id.y; y < coarse_last.y; y++) {
        for (var x = 2u * id.x; x < coarse_last.x; x++) {
            let covered = min(2u * vec2u(x, y) + 2u, vec2u(WIDTH, HEIGHT)) - 2u * vec2u(x, y);
            let weight = f32(covered.x * covered.y) * share;
            for (var c = 0u; c < 3u; c++) {
                low_coarse[c] += coarse[c * half.x * half.y + y * half.x + x] * weight;
            }
        }
    }
    let m = blocks.x * blocks.y;
    let q = id.y * blocks.x + id.x;
    for (var c = 0u; c < 3u; c++) {
        means[c * m + q] = min(low_fine[c], F32_MAX);
        means[(3u + c) * m + q] = min(low_coarse[c], F32_MAX);
    }
    means[6u * m + q] = weight_mean;
}

fn bilinear(plane: u32, at: BlockLookup) -> f32 {
    let base = plane * block_count().x * block_count().y;
    return block_mix(at, means[base + at.i00], means[base + at.i01], means[base + at.i10], means[base + at.i11]);
}

@compute @workgroup_size(8, 8)
fn low_band_apply(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    let n = pixel_count();
    let at = block_lookup(id.xy);
    let w = bilinear(6u, at);
    let epsilon = EPSILON * (exposure[3] * KEY_RATIO);
    for (var c = 0u; c < 3u; c++) {
        let low_fine = bilinear(c, at);
        let low_coarse = bilinear(3u + c, at);
        let numerator = w * low_coarse + (1.0 - w) * low_fine + epsilon;
        let denominator = low_fine + epsilon;
        let value = fine[c * n + i];
        if (denominator > numerator * 1.2676506e30) {
            // A ratio under 2^-100 (a block mean near f32's max) is taken as value / denominator · numerator:
            // a subnormal ratio is flushed to 0 on NVIDIA. Nothing overflows here: the result is < 2^28.
            fine[c * n + i] = quotient(value, denominator) * numerator;
        } else {
            let ratio = min(quotient(numerator, denominator), F32_MAX);
            fine[c * n + i] = min(value * ratio, F32_MAX);
        }
    }
}
