// 2×2 stride-2 transposed convolution on NC4HW4 tensors: every input pixel (y, x) spreads into the
// output pixels (2y+dy, 2x+dx) through its own 4-channel weight block per tap, so each invocation reads
// one input pixel per input block once and writes its four output pixels of one output block group.
// Weights are windows of mat4x4 (4 input × 4 output channels) per (input block, tap, block of group).
{{ENABLE_F16}}
// #import nn_storage.wgsl
// #import nn_activation.wgsl

const IN_H: i32 = {{IN_H}};
const IN_W: i32 = {{IN_W}};
const IN_BLOCK: i32 = {{IN_BLOCK}};
const IN_BLOCKS: i32 = {{IN_BLOCKS}};
const TILE_C: i32 = {{TILE_C}};
const OUT_W: i32 = 2 * IN_W;
const OUT_PLANE: i32 = 4 * IN_H * IN_W;

// #import layer_bindings.wgsl

// 64 invocations cover 8×8 input pixels; no early exit (weight_block may need every lane): out of range
// invocations read a clamped pixel and store nothing.
@compute @workgroup_size(64, 1, 1)
fn main(@builtin(workgroup_id) wid: vec3u, @builtin(local_invocation_id) local_id: vec3u,
        lane: WeightLane) {
    let local = local_id.x;
    let x_unclamped = i32(wid.x) * 8 + i32(local % 8u);
    let y_unclamped = i32(wid.y) * 8 + i32(local / 8u);
    let inside = x_unclamped < IN_W && y_unclamped < IN_H;
    let x = min(x_unclamped, IN_W - 1);
    let y = min(y_unclamped, IN_H - 1);
    var acc: array<vec4f, 4 * TILE_C>;
    for (var t = 0; t < TILE_C; t++) {
        for (var tap = 0; tap < 4; tap++) {
            acc[t * 4 + tap] = header.bias[t];
        }
    }
    for (var cb = 0; cb < IN_BLOCKS; cb++) {
        let value = vec4f(src[(IN_BLOCK + cb) * IN_H * IN_W + y * IN_W + x]);
        for (var tap = 0; tap < 4; tap++) {
            for (var t = 0; t < TILE_C; t++) {
                acc[t * 4 + tap] += weight_block((cb * 4 + tap) * TILE_C + t, lane) * value;
            }
        }
    }
    if (!inside) {
        return;
    }
    for (var t = 0; t < TILE_C; t++) {
        let plane = (header.out_block + t) * OUT_PLANE;
        for (var tap = 0; tap < 4; tap++) {
            let out_index = plane + (2 * y + tap / 2) * OUT_W + 2 * x + tap % 2;
            dst[out_index] = to_storage(activate(acc[t * 4 + tap]));
        }
    }
}
