// Planar NCHW f32 (the pipeline's format) → NC4HW4 of the storage type, on a canvas that may be larger
// than the image (the padding the network's pooling needs). The canvas takes H rows starting at image
// row IN_ROW0 (a band of a frame too big for one pass, or the whole image); canvas pixels past them
// repeat the last row and column (edge padding: an image network sees more of the image at its border,
// not a black frame), and the channels past CHANNELS in the last block are 0. NaN becomes 0 and ±Inf
// the largest finite value.
{{ENABLE_F16}}
// #import nn_storage.wgsl

const CHANNELS: i32 = {{CHANNELS}};
const H: i32 = {{H}};
const W: i32 = {{W}};
const IMAGE_H: i32 = {{IMAGE_H}};
const IN_ROW0: i32 = {{IN_ROW0}};
const CANVAS_H: i32 = {{CANVAS_H}};
const CANVAS_W: i32 = {{CANVAS_W}};
const OUT_BLOCK: i32 = {{OUT_BLOCK}};

@group(0) @binding(0) var<storage, read> planar: array<f32>;
@group(0) @binding(1) var<storage, read_write> dst: array<vec4<T>>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3u) {
    let x = i32(gid.x);
    let y = i32(gid.y);
    let block = i32(gid.z);
    if (x >= CANVAS_W || y >= CANVAS_H) {
        return;
    }
    let source_x = min(x, W - 1);
    let source_y = min(y, H - 1);
    var value = vec4f(0.0);
    for (var k = 0; k < 4; k++) {
        let channel = block * 4 + k;
        if (channel < CHANNELS) {
            value[k] = planar[(channel * IMAGE_H + IN_ROW0 + source_y) * W + source_x];
        }
    }
    dst[(OUT_BLOCK + block) * CANVAS_H * CANVAS_W + y * CANVAS_W + x] = to_storage(value);
}
