// 3×3 stride-1 convolution, one 4-pixel × 16/32-channel register tile (conv3x3_tile.wgsl) per
// invocation, input pixels read straight from device memory: each row step loads its 6 input pixels,
// zero outside the input. The default on adapters whose workgroup memory is no faster than device
// memory (lavapipe: both are per-lane loads) — see conv3x3_staged.wgsl for the staged variant.
{{ENABLE_F16}}
// #import conv3x3_tile.wgsl

// Pixel ix of an input row, zero outside the input (the convolution's zero padding).
fn load_pixel(row: InputRow, row_inside: bool, ix: i32) -> vec4f {
    return select(vec4f(0.0), load_input(row, ix), row_inside && ix >= 0 && ix < IN_W);
}

// 64 invocations cover 8×8 tiles; no early exit (weight_block may need every lane): out of range
// invocations compute on clamped coordinates and store nothing.
@compute @workgroup_size(64, 1, 1)
fn main(@builtin(workgroup_id) wid: vec3u, @builtin(local_invocation_id) local_id: vec3u, lane: WeightLane) {
    enter_group(wid.z);
    let ox0 = i32(wid.x) * TILE_W + i32(local_id.x % 8u) * 4;
    let oy_unclamped = i32(wid.y) * TILE_H + i32(local_id.x / 8u);
    let oy = min(oy_unclamped, OUT_H - 1);
    var tile = bias_tile();
    let ix0 = ox0 - PAD_LEFT;
    for (var cb = 0; cb < IN_BLOCKS; cb++) {
        for (var ky = 0; ky < 3; ky++) {
            let iy = oy + ky - PAD_TOP;
            let row_inside = iy >= 0 && iy < IN_H;
            let row = input_row(cb, iy);
            let r0 = load_pixel(row, row_inside, ix0);
            let r1 = load_pixel(row, row_inside, ix0 + 1);
            let r2 = load_pixel(row, row_inside, ix0 + 2);
            let r3 = load_pixel(row, row_inside, ix0 + 3);
            let r4 = load_pixel(row, row_inside, ix0 + 4);
            let r5 = load_pixel(row, row_inside, ix0 + 5);
            accumulate_row(&tile, cb, ky, lane, r0, r1, r2, r3, r4, r5);
        }
    }
    if (oy_unclamped < OUT_H) {
        store_tile(tile, oy, ox0);
    }
    pool_tile(i32(wid.x) * TILE_W, i32(wid.y) * TILE_H, i32(local_id.x));
}
