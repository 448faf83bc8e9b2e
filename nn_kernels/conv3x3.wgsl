// 3×3 stride-1 convolution with a 4×4 register tile per invocation: 4 adjacent output pixels × 4 output
// channel blocks (16 output channels). Each 3×3 row step loads 6 input pixels (vec4 = 4 input
// channels) once and views them as three 4-pixel matrices (one per kx), so one mat4x4 weight block ×
// mat4x4 pixels product is 64 multiply-adds; the 12 weight blocks of a row step are fetched once per
// invocation and serve all 4 pixels. The tile is written out (no arrays indexed by loop counters):
// lavapipe keeps such code in registers, while loop-indexed tile arrays it could not unroll go to
// scratch memory. The group (4 output blocks), header and weight_block() are as in conv.wgsl.
{{ENABLE_F16}}
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

struct GroupHeader {
    bias: array<vec4f, 4>,
    out_block: i32,
}

@group(0) @binding(0) var<storage, read> src: array<vec4<T>>;
@group(0) @binding(1) var<storage, read_write> dst: array<vec4<T>>;
{{WEIGHT_FETCH}}
@group(0) @binding(3) var<uniform> header: GroupHeader;

fn load_pixel(row_start: i32, row_inside: bool, ix: i32) -> vec4f {
    let value = vec4f(src[row_start + clamp(ix, 0, IN_W - 1)]);
    return select(vec4f(0.0), value, row_inside && ix >= 0 && ix < IN_W);
}

fn store_pixels(block: i32, oy: i32, ox0: i32, pixels: mat4x4f) {
    let base = (header.out_block + block) * OUT_PLANE + oy * OUT_W + ox0;
    for (var p = 0; p < 4; p++) {
        if (ox0 + p < OUT_W) {
            dst[base + p] = to_storage(activate(pixels[p]));
        }
    }
}

// 64 invocations cover 8×8 tiles; no early exit (weight_block may need every lane): out of range
// invocations compute on clamped coordinates and store nothing.
@compute @workgroup_size(64, 1, 1)
fn main(@builtin(workgroup_id) wid: vec3u, @builtin(local_invocation_id) local_id: vec3u, {{LANE}}) {
    let ox0 = (i32(wid.x) * 8 + i32(local_id.x % 8u)) * 4;
    let oy_unclamped = i32(wid.y) * 8 + i32(local_id.x / 8u);
    let oy = min(oy_unclamped, OUT_H - 1);
    // acc_t: columns are the 4 pixels of output block t
    var acc0 = mat4x4f(header.bias[0], header.bias[0], header.bias[0], header.bias[0]);
    var acc1 = mat4x4f(header.bias[1], header.bias[1], header.bias[1], header.bias[1]);
    var acc2 = mat4x4f(header.bias[2], header.bias[2], header.bias[2], header.bias[2]);
    var acc3 = mat4x4f(header.bias[3], header.bias[3], header.bias[3], header.bias[3]);
    let ix0 = ox0 - PAD_LEFT;
    for (var cb = 0; cb < IN_BLOCKS; cb++) {
        let plane = (IN_BLOCK + cb) * IN_H * IN_W;
        for (var ky = 0; ky < 3; ky++) {
            let iy = oy + ky - PAD_TOP;
            let row_inside = iy >= 0 && iy < IN_H;
            let row_start = plane + clamp(iy, 0, IN_H - 1) * IN_W;
            let r0 = load_pixel(row_start, row_inside, ix0);
            let r1 = load_pixel(row_start, row_inside, ix0 + 1);
            let r2 = load_pixel(row_start, row_inside, ix0 + 2);
            let r3 = load_pixel(row_start, row_inside, ix0 + 3);
            let r4 = load_pixel(row_start, row_inside, ix0 + 4);
            let r5 = load_pixel(row_start, row_inside, ix0 + 5);
            let x0 = mat4x4f(r0, r1, r2, r3);
            let x1 = mat4x4f(r1, r2, r3, r4);
            let x2 = mat4x4f(r2, r3, r4, r5);
            let tap = (cb * 3 + ky) * 3 * 4;  // weight blocks of (kx, t) follow at tap + kx * 4 + t
            acc0 += weight_block(tap, lane) * x0 + weight_block(tap + 4, lane) * x1
                + weight_block(tap + 8, lane) * x2;
            acc1 += weight_block(tap + 1, lane) * x0 + weight_block(tap + 5, lane) * x1
                + weight_block(tap + 9, lane) * x2;
            acc2 += weight_block(tap + 2, lane) * x0 + weight_block(tap + 6, lane) * x1
                + weight_block(tap + 10, lane) * x2;
            acc3 += weight_block(tap + 3, lane) * x0 + weight_block(tap + 7, lane) * x1
                + weight_block(tap + 11, lane) * x2;
        }
    }
    if (oy_unclamped < OUT_H) {
        store_pixels(0, oy, ox0, acc0);
        store_pixels(1, oy, ox0, acc1);
        store_pixels(2, oy, ox0, acc2);
        store_pixels(3, oy, ox0, acc3);
    }
}
