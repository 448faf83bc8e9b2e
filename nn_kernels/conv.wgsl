// Tiled direct convolution (k×k, stride 1 or 2, zero padding) on NC4HW4 tensors.
// A workgroup computes TILE_C output channel blocks (4·TILE_C channels, one "group": workgroup_id.z,
// see layer_bindings.wgsl); each invocation owns TILE_X horizontally adjacent output pixels of those
// blocks, so every input row segment it loads (a vec4 = 4 input channels) is reused across the KW
// taps and TILE_X pixels, and every weight block (a mat4x4: 4 input × 4 output channels) across
// TILE_X pixels. Weights of the group are
// one window of the layer's weights, read through weight_block() (weights_subgroup.wgsl: the lanes
// split a block's loads and broadcast them; else weights_uniform.wgsl). The group's bias and output
// block come in its uniform header; bias and activation run in the epilogue. Shapes are pipeline constants.
// The engine runs here the convolutions conv3x3.wgsl does not take (other sizes, stride 2, outputs that
// are not a multiple of 16 channels); with TILE_X = 1 it is the benchmark's naive step. Inputs, outputs
// and the pooling epilogue as in conv3x3_tile.wgsl.
{{ENABLE_F16}}
// #import nn_storage.wgsl
// #import nn_activation.wgsl
// #import pool_epilogue.wgsl

const IN_H: i32 = {{IN_H}};
const IN_W: i32 = {{IN_W}};
const IN_BLOCK: i32 = {{IN_BLOCK}};
const IN_BLOCKS: i32 = {{IN_BLOCKS}};
const OUT_H: i32 = {{OUT_H}};
const OUT_W: i32 = {{OUT_W}};
const KH: i32 = {{KH}};
const KW: i32 = {{KW}};
const STRIDE: i32 = {{STRIDE}};
const PAD_TOP: i32 = {{PAD_TOP}};
const PAD_LEFT: i32 = {{PAD_LEFT}};
const TILE_X: i32 = {{TILE_X}};
const TILE_C: i32 = {{TILE_C}};
const ROW_LEN: i32 = (TILE_X - 1) * STRIDE + KW;
const OUT_PLANE: i32 = OUT_H * OUT_W;
const TILE_W: i32 = 8 * TILE_X;  // output pixels of a workgroup's tile
const TILE_H: i32 = 8;

// #import load_blocks.wgsl
// #import layer_bindings.wgsl

// 64 invocations cover an 8×8 block of tiles; no early exit (weight_block may need every lane), out of
// range invocations compute on clamped coordinates and store nothing (but join the pooling epilogue).
@compute @workgroup_size(64, 1, 1)
fn main(@builtin(workgroup_id) wid: vec3u, @builtin(local_invocation_id) local_id: vec3u,
        lane: WeightLane) {
    enter_group(wid.z);
    let local = local_id.x;
    let ox0 = (i32(wid.x) * 8 + i32(local % 8u)) * TILE_X;
    let oy_unclamped = i32(wid.y) * 8 + i32(local / 8u);
    let oy = min(oy_unclamped, OUT_H - 1);
    var acc: array<vec4f, TILE_X * TILE_C>;
    for (var t = 0; t < TILE_C; t++) {
        for (var p = 0; p < TILE_X; p++) {
            acc[t * TILE_X + p] = header.bias[t];
        }
    }
    let ix0 = ox0 * STRIDE - PAD_LEFT;
    for (var cb = 0; cb < IN_BLOCKS; cb++) {
        for (var ky = 0; ky < KH; ky++) {
            let iy = oy * STRIDE + ky - PAD_TOP;
            let row_inside = iy >= 0 && iy < IN_H;
            let input = input_row(cb, iy);
            var row: array<vec4f, ROW_LEN>;
            for (var i = 0; i < ROW_LEN; i++) {
                let ix = ix0 + i;
                row[i] = select(vec4f(0.0), load_input(input, ix), row_inside && ix >= 0 && ix < IN_W);
            }
            for (var kx = 0; kx < KW; kx++) {
                for (var t = 0; t < TILE_C; t++) {
                    let w = weight_block(((cb * KH + ky) * KW + kx) * TILE_C + t, lane);
                    for (var p = 0; p < TILE_X; p++) {
                        acc[t * TILE_X + p] += w * row[p * STRIDE + kx];
                    }
                }
            }
        }
    }
    for (var t = 0; t < TILE_C; t++) {
        for (var p = 0; p < TILE_X; p++) {
            if (ox0 + p < OUT_W && oy_unclamped < OUT_H) {
                store_output(header.out_block + t, oy * OUT_W + ox0 + p, activate(acc[t * TILE_X + p]));
            }
        }
    }
    pool_tile(i32(wid.x) * TILE_W, i32(wid.y) * TILE_H, i32(local));
}
