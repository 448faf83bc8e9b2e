// The 16-channel width of conv3x3_tile.wgsl: 4 pixels × 4 output blocks (two pair windows) per
// invocation, for layers whose output has 16k channels but not 32k, and for every layer of
// conv3x3_staged.wgsl.
const TILE_C: i32 = 4;

// block_t: columns are the 4 pixels of output block t of the group
struct Tile {
    block0: mat4x4f,
    block1: mat4x4f,
    block2: mat4x4f,
    block3: mat4x4f,
}

fn bias_tile() -> Tile {
    return Tile(bias_pixels(0), bias_pixels(1), bias_pixels(2), bias_pixels(3));
}

// Adds kernel row ky of input block cb: r0..r5 are the input pixels ox0 - PAD_LEFT + 0..5 of the row.
// Call from uniform control flow (the weight fetch may use subgroup operations).
fn accumulate_row(tile: ptr<function, Tile>, cb: i32, ky: i32, lane: WeightLane,
                  r0: vec4f, r1: vec4f, r2: vec4f, r3: vec4f, r4: vec4f, r5: vec4f) {
    let x = kernel_row(r0, r1, r2, r3, r4, r5);
    let tap = row_tap(cb, ky);
    (*tile).block0 += pair0_weight_block(tap, lane) * x.x0 + pair0_weight_block(tap + 2, lane) * x.x1
        + pair0_weight_block(tap + 4, lane) * x.x2;
    (*tile).block1 += pair0_weight_block(tap + 1, lane) * x.x0 + pair0_weight_block(tap + 3, lane) * x.x1
        + pair0_weight_block(tap + 5, lane) * x.x2;
    (*tile).block2 += pair1_weight_block(tap, lane) * x.x0 + pair1_weight_block(tap + 2, lane) * x.x1
        + pair1_weight_block(tap + 4, lane) * x.x2;
    (*tile).block3 += pair1_weight_block(tap + 1, lane) * x.x0 + pair1_weight_block(tap + 3, lane) * x.x1
        + pair1_weight_block(tap + 5, lane) * x.x2;
}

fn store_tile(tile: Tile, oy: i32, ox0: i32) {
    store_pixels(0, oy, ox0, tile.block0);
    store_pixels(1, oy, ox0, tile.block1);
    store_pixels(2, oy, ox0, tile.block2);
    store_pixels(3, oy, ox0, tile.block3);
}
