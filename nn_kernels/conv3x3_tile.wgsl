// The register tile shared by the 3×3 stride-1 kernels (conv3x3.wgsl, conv3x3_staged.wgsl): the layer's
// constants and bindings, and a tile of 4 adjacent output pixels × TILE_C output channel blocks per
// invocation. Its width, TILE_C (4 blocks, 16 channels; 8 blocks, 32 channels in conv3x3.wgsl on layers
// whose output has a multiple of 32 channels; 2 blocks where 16 channels do not divide the output), is
// unrolled in conv3x3_tile_blocks.wgsl. One row step takes the 6 input pixels (vec4 = 4
// input channels) of one kernel row and views them as three 4-pixel matrices (one per kx), so one
// mat4x4 weight block × mat4x4 pixels product is 64 multiply-adds, and every weight block of a row
// step is fetched once per invocation and serves all 4 pixels. The tile is named matrices, not an
// array indexed by loop counters: lavapipe keeps such code in registers, while loop-indexed tile
// arrays it could not unroll go to scratch memory. The group (TILE_C output blocks) and header are as
// in conv.wgsl; its weights come in one window per pair of output blocks (kernels.PackedWeights with
// splits = TILE_C / 2): blocks 2p and 2p + 1 from window `pair{p}_weights` (pair{p}_weight_block),
// so 128 input channels still fit 64 KiB uniform bindings. Input pixels come through load_input
// (load_blocks.wgsl, or the planar input image: load_planar.wgsl), outputs go through store_output
// (store_blocks.wgsl, or the planar output image: store_planar.wgsl), and the epilogue may also max-pool
// the workgroup's tile (pool_epilogue.wgsl) or run the network's 1×1 head (head_epilogue.wgsl).
// #import nn_storage.wgsl
// #import nn_activation.wgsl
// #import pool_epilogue.wgsl
// #import head_epilogue_none.wgsl
// #import load_blocks.wgsl
// #import layer_bindings.wgsl
// #import conv3x3_tile_blocks.wgsl

const IN_H: i32 = {{IN_H}};
const IN_W: i32 = {{IN_W}};
const IN_BLOCK: i32 = {{IN_BLOCK}};
const IN_BLOCKS: i32 = {{IN_BLOCKS}};
const PAD_TOP: i32 = {{PAD_TOP}};
const PAD_LEFT: i32 = {{PAD_LEFT}};
const OUT_H: i32 = {{OUT_H}};
const OUT_W: i32 = {{OUT_W}};
const OUT_PLANE: i32 = OUT_H * OUT_W;
const TILE_W: i32 = 32;  // a workgroup's output tile: 8 × 8 invocations of 4 pixels each
const TILE_H: i32 = 8;

// The type a kernel row's multiply-adds run in: f32, or f16 (kernels.Conv3x3Kernel with half_math: the
// row's 3 × 4 input channels summed in packed half precision, then added to the f32 tile).
alias RowMat = mat4x4<{{MATH}}>;

// The three 4-pixel input matrices of one kernel row (column p: input pixel p + kx of the row), from
// its 6 input pixels r0..r5.
struct KernelRow {
    x0: RowMat,
    x1: RowMat,
    x2: RowMat,
}

fn kernel_row(r0: vec4f, r1: vec4f, r2: vec4f, r3: vec4f, r4: vec4f, r5: vec4f) -> KernelRow {
    let p0 = vec4<{{MATH}}>(r0);
    let p1 = vec4<{{MATH}}>(r1);
    let p2 = vec4<{{MATH}}>(r2);
    let p3 = vec4<{{MATH}}>(r3);
    let p4 = vec4<{{MATH}}>(r4);
    let p5 = vec4<{{MATH}}>(r5);
    return KernelRow(RowMat(p0, p1, p2, p3), RowMat(p1, p2, p3, p4), RowMat(p2, p3, p4, p5));
}

// Index of the first weight block of row step (cb, ky) in every pair window: the window's blocks of
// (kx, t) follow at row_tap + kx * 2 + t, t = 0 for the pair's even output block, 1 for its odd one.
fn row_tap(cb: i32, ky: i32) -> i32 {
    return (cb * 3 + ky) * 3 * 2;
}

fn bias_pixels(block: i32) -> mat4x4f {
    return mat4x4f(header.bias[block], header.bias[block], header.bias[block], header.bias[block]);
}

fn store_pixels(block: i32, oy: i32, ox0: i32, pixels: mat4x4f) {
    for (var p = 0; p < 4; p++) {
        if (ox0 + p < OUT_W) {
            store_output(header.out_block + block, oy * OUT_W + ox0 + p, activate(pixels[p]));
        }
    }
}
