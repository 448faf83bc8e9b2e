// 2×2 stride-2 transposed convolution on NC4HW4 tensors: every input pixel (y, x) spreads into the
// output pixels (2y+dy, 2x+dx) through its own 4-channel weight block per tap (dy, dx). Each invocation
// takes 4 adjacent input pixels of one row and one output block: per input block it loads the 4 pixels
// once (a mat4x4 whose columns are the pixels) and multiplies them by the 4 taps' weight blocks, so
// each fetched weight block (4 input × 4 output channels) feeds 4 pixels, 64 multiply-adds. The four
// tap accumulators are named matrices, not an indexed array, so they stay in registers (lavapipe).
// Weights are windows of mat4x4 per (input block, tap) of the workgroup's output block (TILE_C = 1, one
// group per output block, workgroup_id.z: layer_bindings.wgsl).
{{ENABLE_F16}}
// #import nn_storage.wgsl
// #import nn_activation.wgsl

const IN_H: i32 = {{IN_H}};
const IN_W: i32 = {{IN_W}};
const IN_BLOCK: i32 = {{IN_BLOCK}};
const IN_BLOCKS: i32 = {{IN_BLOCKS}};
const TILE_C: i32 = 1;
const OUT_W: i32 = 2 * IN_W;
const OUT_PLANE: i32 = 4 * IN_H * IN_W;

// #import input_binding.wgsl
// #import layer_bindings.wgsl

fn load_pixel(row_start: i32, x: i32) -> vec4f {
    return vec4f(src[row_start + min(x, IN_W - 1)]);
}

// Output pixels (2y + dy, 2x + dx) of input pixels x0..x0+3 for tap (dy, dx): column p is pixel x0 + p.
fn store_tap(y: i32, x0: i32, dy: i32, dx: i32, pixels: mat4x4f) {
    let row_start = (2 * y + dy) * OUT_W + dx;
    for (var p = 0; p < 4; p++) {
        if (x0 + p < IN_W) {
            store_output(header.out_block, row_start + 2 * (x0 + p), activate(pixels[p]));
        }
    }
}

// 64 invocations cover 8 rows × 32 input pixels; no early exit (weight_block may need every lane): out
// of range invocations read clamped pixels and store nothing.
@compute @workgroup_size(64, 1, 1)
fn main(@builtin(workgroup_id) wid: vec3u, @builtin(local_invocation_id) local_id: vec3u,
        lane: WeightLane) {
    enter_group(wid.z);
    let x0 = (i32(wid.x) * 8 + i32(local_id.x % 8u)) * 4;
    let y_unclamped = i32(wid.y) * 8 + i32(local_id.x / 8u);
    let y = min(y_unclamped, IN_H - 1);
    let bias = mat4x4f(header.bias[0], header.bias[0], header.bias[0], header.bias[0]);
    var tap00 = bias;
    var tap01 = bias;
    var tap10 = bias;
    var tap11 = bias;
    for (var cb = 0; cb < IN_BLOCKS; cb++) {
        let row_start = (IN_BLOCK + cb) * IN_H * IN_W + y * IN_W;
        let pixels = mat4x4f(load_pixel(row_start, x0), load_pixel(row_start, x0 + 1),
                             load_pixel(row_start, x0 + 2), load_pixel(row_start, x0 + 3));
        tap00 += weight_block(cb * 4, lane) * pixels;
        tap01 += weight_block(cb * 4 + 1, lane) * pixels;
        tap10 += weight_block(cb * 4 + 2, lane) * pixels;
        tap11 += weight_block(cb * 4 + 3, lane) * pixels;
    }
    if (y_unclamped < IN_H) {
        store_tap(y, x0, 0, 0, tap00);
        store_tap(y, x0, 0, 1, tap01);
        store_tap(y, x0, 1, 0, tap10);
        store_tap(y, x0, 1, 1, tap11);
    }
}
