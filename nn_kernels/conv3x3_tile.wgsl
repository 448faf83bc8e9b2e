// The register tile shared by the 3×3 stride-1 kernels (conv3x3.wgsl, conv3x3_staged.wgsl): the layer's
// constants and bindings, and a tile of 4 adjacent output pixels × 4 output channel blocks (16
// channels). One row step takes the 6 input pixels (vec4 = 4 input channels) of one kernel row and
// views them as three 4-pixel matrices (one per kx), so one mat4x4 weight block × mat4x4 pixels
// product is 64 multiply-adds; the 12 weight blocks of a row step are fetched once per invocation and
// serve all 4 pixels. The tile is four named matrices, not an array indexed by loop counters: lavapipe
// keeps such code in registers, while loop-indexed tile arrays it could not unroll go to scratch
// memory. The group (4 output blocks) and header are as in conv.wgsl; its weights come in two windows
// (kernels.PackedWeights with halves=2): blocks 0–1 from `weights` (weight_block), 2–3 from
// `high_weights` (high_weight_block), so 128 input channels still fit two 64 KiB uniform bindings.
// #import nn_storage.wgsl
// #import nn_activation.wgsl

const IN_H: i32 = {{IN_H}};
const IN_W: i32 = {{IN_W}};
const IN_BLOCK: i32 = {{IN_BLOCK}};
const IN_BLOCKS: i32 = {{IN_BLOCKS}};
const PAD_TOP: i32 = {{PAD_TOP}};
const PAD_LEFT: i32 = {{PAD_LEFT}};
const OUT_H: i32 = {{OUT_H}};
const OUT_W: i32 = {{OUT_W}};
const OUT_PLANE: i32 = OUT_H * OUT_W;

const TILE_C: i32 = 4;   // output channel blocks per invocation
// #import layer_bindings.wgsl

// block_t: columns are the 4 pixels of output block t of the group
struct Tile {
    block0: mat4x4f,
    block1: mat4x4f,
    block2: mat4x4f,
    block3: mat4x4f,
}

fn bias_tile() -> Tile {
    return Tile(mat4x4f(header.bias[0], header.bias[0], header.bias[0], header.bias[0]),
                mat4x4f(header.bias[1], header.bias[1], header.bias[1], header.bias[1]),
                mat4x4f(header.bias[2], header.bias[2], header.bias[2], header.bias[2]),
                mat4x4f(header.bias[3], header.bias[3], header.bias[3], header.bias[3]));
}

// Adds kernel row ky of input block cb: r0..r5 are the input pixels ox0 - PAD_LEFT + 0..5 of the row.
// Call from uniform control flow (weight_block may use subgroup operations).
fn accumulate_row(tile: ptr<function, Tile>, cb: i32, ky: i32, lane: WeightLane,
                  r0: vec4f, r1: vec4f, r2: vec4f, r3: vec4f, r4: vec4f, r5: vec4f) {
    let x0 = mat4x4f(r0, r1, r2, r3);
    let x1 = mat4x4f(r1, r2, r3, r4);
    let x2 = mat4x4f(r2, r3, r4, r5);
    let tap = (cb * 3 + ky) * 3 * 2;  // each window's blocks of (kx, t) follow at tap + kx * 2 + t % 2
    (*tile).block0 += weight_block(tap, lane) * x0 + weight_block(tap + 2, lane) * x1
        + weight_block(tap + 4, lane) * x2;
    (*tile).block1 += weight_block(tap + 1, lane) * x0 + weight_block(tap + 3, lane) * x1
        + weight_block(tap + 5, lane) * x2;
    (*tile).block2 += high_weight_block(tap, lane) * x0 + high_weight_block(tap + 2, lane) * x1
        + high_weight_block(tap + 4, lane) * x2;
    (*tile).block3 += high_weight_block(tap + 1, lane) * x0 + high_weight_block(tap + 3, lane) * x1
        + high_weight_block(tap + 5, lane) * x2;
}

fn store_pixels(block: i32, oy: i32, ox0: i32, pixels: mat4x4f) {
    let base = (header.out_block + block) * OUT_PLANE + oy * OUT_W + ox0;
    for (var p = 0; p < 4; p++) {
        if (ox0 + p < OUT_W) {
            dst[base + p] = to_storage(activate(pixels[p]));
        }
    }
}

fn store_tile(tile: Tile, oy: i32, ox0: i32) {
    store_pixels(0, oy, ox0, tile.block0);
    store_pixels(1, oy, ox0, tile.block1);
    store_pixels(2, oy, ox0, tile.block2);
    store_pixels(3, oy, ox0, tile.block3);
}
