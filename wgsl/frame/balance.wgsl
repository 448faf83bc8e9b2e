// The denoiser's white balance (frame/pack.py's white_balance_gains), found on the device in two dispatches so
// that packing needs no CPU round trip. The irradiance is what pack_denoiser demodulates: sanitised
// colour / albedo_factor, each pixel's clamped to IRRADIANCE_LIMIT so that the sums stay finite.
//   tile_sums_main: each 8×8 workgroup sums its pixels' irradiance (tree reduction in workgroup memory) into
//                   tile_sums[3·tile + c], tiles numbered row by row;
//   gains_main:     one workgroup of 256 sums the tiles' sums (each invocation a strided share, then a
//                   tree), divides by the pixel count and writes balance[c] = max(mean_c^POWER / mean of
//                   the three, FLOOR), or 1 for every channel when the frame is black.
// #import frame/common.wgsl
// #import frame/albedo.wgsl

const IRRADIANCE_LIMIT: f32 = 1e30;
const GAINS_WORKGROUP: u32 = 256u;
override POWER: f32 = 0.5;
override FLOOR: f32 = 0.0625;

@group(0) @binding(0) var<storage, read> color: array<f32>;
@group(0) @binding(1) var<storage, read> albedo: array<f32>;
@group(0) @binding(2) var<storage, read_write> tile_sums: array<f32>;
@group(0) @binding(3) var<storage, read_write> balance: array<f32>;

var<workgroup> partial: array<vec3f, GAINS_WORKGROUP>;

fn tiles_across() -> u32 { return (WIDTH + TILE - 1u) / TILE; }

fn tile_count() -> u32 { return tiles_across() * ((HEIGHT + TILE - 1u) / TILE); }

// Sums partial[0..size) into partial[0] (size a power of two).
fn reduce_partial(lane: u32, size: u32) {
    for (var stride = size / 2u; stride > 0u; stride = stride >> 1u) {
        if (lane < stride) { partial[lane] += partial[lane + stride]; }
        workgroupBarrier();
    }
}

@compute @workgroup_size(8, 8)
fn tile_sums_main(@builtin(global_invocation_id) id: vec3u, @builtin(local_invocation_index) lane: u32,
                  @builtin(workgroup_id) tile: vec3u) {
    var irradiance = vec3f(0.0);
    if (in_frame(id)) {
        let i = pixel_index(id);
        let n = pixel_count();
        for (var c = 0u; c < 3u; c++) {
            irradiance[c] = min(sanitize(color[c * n + i]) / albedo_factor(albedo[c * n + i]), IRRADIANCE_LIMIT);
        }
    }
    partial[lane] = irradiance;
    workgroupBarrier();
    reduce_partial(lane, TILE * TILE);
    if (lane == 0u) {
        let t = tile.y * tiles_across() + tile.x;
        for (var c = 0u; c < 3u; c++) { tile_sums[3u * t + c] = partial[0][c]; }
    }
}

@compute @workgroup_size(GAINS_WORKGROUP)
fn gains_main(@builtin(local_invocation_index) lane: u32) {
    var sum = vec3f(0.0);
    for (var t = lane; t < tile_count(); t += GAINS_WORKGROUP) {
        sum += vec3f(tile_sums[3u * t], tile_sums[3u * t + 1u], tile_sums[3u * t + 2u]);
    }
    partial[lane] = sum;
    workgroupBarrier();
    reduce_partial(lane, GAINS_WORKGROUP);
    if (lane == 0u) {
        let mean = partial[0] / f32(pixel_count());
        var gains = vec3f(1.0);
        if (max(mean.x, max(mean.y, mean.z)) > 0.0) {
            let powered = select(vec3f(0.0), pow(mean, vec3f(POWER)), mean > vec3f(0.0));   // pow(0, y) undefined
            gains = max(powered / ((powered.x + powered.y + powered.z) / 3.0), vec3f(FLOOR));
        }
        for (var c = 0u; c < 3u; c++) { balance[c] = gains[c]; }
    }
}
