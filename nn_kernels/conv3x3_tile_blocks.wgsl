// The register tile's width: TILE_C output blocks (2: 8 channels, 4: 16, 8: 32) of 4 pixels each,
// written out by kernels.tile_blocks_code, which unrolls the fields, the bias, the accumulation (blocks
// 2p and 2p + 1 from pair window p) and the stores below for the width a layer takes. The 32-channel
// tile serves twice the multiply-adds per input pixel loaded, and input loads are lavapipe's bottleneck
// (a storage load is a scalar loop over the lanes): it takes 3–12% less CPU time than the 16-channel
// one on every 3×3 layer shape of the U-Net (kernels.Conv3x3Kernel). Named matrices, not a loop-indexed
// array: lavapipe keeps such code in registers.
const TILE_C: i32 = {{TILE_C}};

// block_t: columns are the 4 pixels of output block t of the group
struct Tile {
{{TILE_FIELDS}}
}

fn bias_tile() -> Tile {
    return Tile({{TILE_BIAS}});
}

// Adds kernel row ky of input block cb: r0..r5 are the input pixels ox0 - PAD_LEFT + 0..5 of the row.
// Call from uniform control flow (the weight fetch may use subgroup operations).
fn accumulate_row(tile: ptr<function, Tile>, cb: i32, ky: i32, lane: WeightLane,
                  r0: vec4f, r1: vec4f, r2: vec4f, r3: vec4f, r4: vec4f, r5: vec4f) {
    let x = kernel_row(r0, r1, r2, r3, r4, r5);
    let tap = row_tap(cb, ky);
{{TILE_ACCUMULATE}}
}

// Stores the tile's pixels of output row oy (or, with a head folded in, the head's output of them).
fn store_tile(tile: Tile, oy: i32, ox0: i32) {
{{TILE_STORE}}
}
