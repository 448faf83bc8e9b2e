// The denoiser's white balance (frame/pack.py's white_balance_gains), found on the device in two dispatches so
// that packing needs no CPU round trip. The irradiance is what pack_denoiser demodulates: sanitised
// colour / albedo_factor, each pixel's clamped to IRRADIANCE_LIMIT so that the sums stay finite.
//   tile_sums_main: each 8×8 workgroup sums its pixels' irradiance (tree reduction in workgroup memory) into
//                   tile_sums[3·tile + c], tiles numbered row by row;
//   gains_main:     one workgroup of 256 sums the tiles' sums (each invocation a strided share, then a
//                   tree), divides by the pixel count and writes balance[c] = max(mean_c^POWER / mean of
//                   the three, FLOOR), or 1 for every channel when the frame is black or without
//                   BALANCE; with EXPOSURE, times the frame's exposure scale (pack.py's exposure_scale):
//                   its key, exp of the mean log of the tiles' mean luminance over the tiles brighter than
//                   KEY_FLOOR, over KEY, summed in the same shares and tree; balance[3] is that scale
//                   whether or not the gains carry it (the low band, chroma hold and post filter read the
//                   frame at one key with it).
// Without DEMODULATE the key is the colour's own, not its irradiance's (pack.py's RadianceExposurePass: the error
// predictor's probe, the confidence model's frame): albedo is then not read (its binding is handed the colour).
// #import frame/common.wgsl
// #import frame/albedo.wgsl

const IRRADIANCE_LIMIT: f32 = 1e30;
const GAINS_WORKGROUP: u32 = 256u;
override POWER: f32 = 0.5;
override FLOOR: f32 = 0.0625;
override BALANCE: bool = true;
override EXPOSURE: bool = true;
override KEY: f32 = 0.3;
override KEY_FLOOR: f32 = 1e-8;
override EXPOSURE_LIMIT: f32 = 1.8446744e19;   // 2^64
override DEMODULATE: bool = true;

@group(0) @binding(0) var<storage, read> color: array<f32>;
@group(0) @binding(1) var<storage, read> albedo: array<f32>;
@group(0) @binding(2) var<storage, read_write> tile_sums: array<f32>;
@group(0) @binding(3) var<storage, read_write> balance: array<f32>;

var<workgroup> partial: array<vec3f, GAINS_WORKGROUP>;
var<workgroup> key_partial: array<vec2f, GAINS_WORKGROUP>;   // (sum of the tiles' log luminance, tile count)

fn tiles_across() -> u32 { return (WIDTH + TILE - 1u) / TILE; }

fn tile_count() -> u32 { return tiles_across() * ((HEIGHT + TILE - 1u) / TILE); }

// Sums partial[0..size) into partial[0] (size a power of two), and key_partial likewise where `keyed` (the
// gains pass; the per-tile pass has no key to sum).
fn reduce_partial(lane: u32, size: u32, keyed: bool) {
    for (var stride = size / 2u; stride > 0u; stride = stride >> 1u) {
        if (lane < stride) {
            partial[lane] += partial[lane + stride];
            if (keyed) { key_partial[lane] += key_partial[lane + stride]; }
        }
        workgroupBarrier();
    }
}

// The pixels of tile t that lie in the frame (fewer at its right and bottom edges).
fn tile_pixels(t: u32) -> f32 {
    let corner = vec2u(t % tiles_across(), t / tiles_across()) * TILE;
    let covered = min(corner + TILE, vec2u(WIDTH, HEIGHT)) - corner;
    return f32(covered.x * covered.y);
}

@compute @workgroup_size(8, 8)
fn tile_sums_main(@builtin(global_invocation_id) id: vec3u, @builtin(local_invocation_index) lane: u32,
                  @builtin(workgroup_id) tile: vec3u) {
    var irradiance = vec3f(0.0);
    if (in_frame(id)) {
        let i = pixel_index(id);
        let n = pixel_count();
        for (var c = 0u; c < 3u; c++) {
            var factor = 1.0;
            if (DEMODULATE) { factor = albedo_factor(albedo[c * n + i]); }
            irradiance[c] = min(sanitize(color[c * n + i]) / factor, IRRADIANCE_LIMIT);
        }
    }
    partial[lane] = irradiance;
    workgroupBarrier();
    reduce_partial(lane, TILE * TILE, false);
    if (lane == 0u) {
        let t = tile.y * tiles_across() + tile.x;
        for (var c = 0u; c < 3u; c++) { tile_sums[3u * t + c] = partial[0][c]; }
    }
}

@compute @workgroup_size(GAINS_WORKGROUP)
fn gains_main(@builtin(local_invocation_index) lane: u32) {
    var sum = vec3f(0.0);
    var key_sum = vec2f(0.0);
    for (var t = lane; t < tile_count(); t += GAINS_WORKGROUP) {
        let tile_sum = vec3f(tile_sums[3u * t], tile_sums[3u * t + 1u], tile_sums[3u * t + 2u]);
        sum += tile_sum;
        let luminance = (tile_sum.x + tile_sum.y + tile_sum.z) / 3.0 / tile_pixels(t);
        if (luminance > KEY_FLOOR) { key_sum += vec2f(log(luminance), 1.0); }
    }
    partial[lane] = sum;
    key_partial[lane] = key_sum;
    workgroupBarrier();
    reduce_partial(lane, GAINS_WORKGROUP, true);
    if (lane == 0u) {
        let mean = partial[0] / f32(pixel_count());
        var gains = vec3f(1.0);
        if (BALANCE && max(mean.x, max(mean.y, mean.z)) > 0.0) {
            let powered = select(vec3f(0.0), pow(mean, vec3f(POWER)), mean > vec3f(0.0));   // pow(0, y) undefined
            gains = max(powered / ((powered.x + powered.y + powered.z) / 3.0), vec3f(FLOOR));
        }
        let keyed = key_partial[0];
        var scale = 1.0;
        if (keyed.y > 0.0) { scale = clamp(exp(keyed.x / keyed.y) / KEY, 1.0 / EXPOSURE_LIMIT, EXPOSURE_LIMIT); }
        if (EXPOSURE) { gains *= scale; }
        balance[3] = scale;
        for (var c = 0u; c < 3u; c++) { balance[c] = gains[c]; }
    }
}
