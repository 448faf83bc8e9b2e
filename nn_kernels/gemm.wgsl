// 1×1 convolution as a GEMM over flattened pixels (NC4HW4): out[co, p] = bias[co] + Σ W[co, ci]·x[ci, p].
// Each invocation owns TILE_X consecutive pixels of TILE_C output channel blocks, so one vec4 input
// load (4 channels of one pixel) feeds 4·4·TILE_C multiply-adds and one weight mat4x4 serves TILE_X
// pixels. No halo and no bounds per tap: the pixel range is a flat line. Weights and header as in
// conv.wgsl.
{{ENABLE_F16}}
// #import nn_storage.wgsl
// #import nn_activation.wgsl

const PIXELS: i32 = {{PIXELS}};
const IN_BLOCK: i32 = {{IN_BLOCK}};
const IN_BLOCKS: i32 = {{IN_BLOCKS}};
const TILE_X: i32 = {{TILE_X}};
const TILE_C: i32 = {{TILE_C}};
const OUT_W: i32 = {{OUT_W}};  // pixels per row (store_planar.wgsl)
const OUT_PLANE: i32 = PIXELS;

// #import input_binding.wgsl
// #import layer_bindings.wgsl

// No early exit (weight_block may need every lane): out of range tiles read clamped pixels, store nothing.
@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3u, lane: WeightLane) {
    enter_group(gid.z);  // workgroups are 64×1×1, so gid.z is workgroup_id.z
    let p0 = i32(gid.x) * TILE_X;
    var acc: array<vec4f, TILE_X * TILE_C>;
    for (var t = 0; t < TILE_C; t++) {
        for (var p = 0; p < TILE_X; p++) {
            acc[t * TILE_X + p] = header.bias[t];
        }
    }
    for (var cb = 0; cb < IN_BLOCKS; cb++) {
        let plane = (IN_BLOCK + cb) * PIXELS;
        var column: array<vec4f, TILE_X>;
        for (var p = 0; p < TILE_X; p++) {
            column[p] = vec4f(src[plane + min(p0 + p, PIXELS - 1)]);
        }
        for (var t = 0; t < TILE_C; t++) {
            let w = weight_block(cb * TILE_C + t, lane);
            for (var p = 0; p < TILE_X; p++) {
                acc[t * TILE_X + p] += w * column[p];
            }
        }
    }
    for (var t = 0; t < TILE_C; t++) {
        for (var p = 0; p < TILE_X; p++) {
            if (p0 + p < PIXELS) {
                store_output(header.out_block + t, p0 + p, activate(acc[t * TILE_X + p]));
            }
        }
    }
}
