// NC4HW4 of the storage type → planar NCHW f32, cropping the canvas back to the image and dropping the
// padding channels of the last block: canvas rows ROW_FROM.. ROW_FROM+H-1 (the first W columns) go to
// image rows OUT_ROW0.. of an IMAGE_H-row image. One invocation per output pixel and block.
{{ENABLE_F16}}
// #import nn_storage.wgsl

const CHANNELS: i32 = {{CHANNELS}};
const H: i32 = {{H}};
const W: i32 = {{W}};
const IMAGE_H: i32 = {{IMAGE_H}};
const OUT_ROW0: i32 = {{OUT_ROW0}};
const ROW_FROM: i32 = {{ROW_FROM}};
const CANVAS_H: i32 = {{CANVAS_H}};
const CANVAS_W: i32 = {{CANVAS_W}};
const IN_BLOCK: i32 = {{IN_BLOCK}};

@group(0) @binding(0) var<storage, read> src: array<vec4<T>>;
@group(0) @binding(1) var<storage, read_write> planar: array<f32>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3u) {
    let x = i32(gid.x);
    let y = i32(gid.y);
    let block = i32(gid.z);
    if (x >= W || y >= H) {
        return;
    }
    let value = vec4f(src[(IN_BLOCK + block) * CANVAS_H * CANVAS_W + (ROW_FROM + y) * CANVAS_W + x]);
    for (var k = 0; k < 4; k++) {
        let channel = block * 4 + k;
        if (channel < CHANNELS) {
            planar[(channel * IMAGE_H + OUT_ROW0 + y) * W + x] = value[k];
        }
    }
}
