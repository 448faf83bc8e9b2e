// NC4HW4 of the storage type → planar NCHW f32 (store_planar.wgsl: cropped to the image): the exit
// conversion where the network's last layer does not write the image itself (kernels.UnpackKernel).
// One invocation per canvas pixel of the kept rows and block.
{{ENABLE_F16}}
// #import nn_storage.wgsl
// #import store_planar.wgsl

const CANVAS_H: i32 = {{CANVAS_H}};
const OUT_W: i32 = {{CANVAS_W}};
const IN_BLOCK: i32 = {{IN_BLOCK}};

@group(0) @binding(0) var<storage, read> src: array<vec4<T>>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3u) {
    let x = i32(gid.x);
    let y = i32(gid.y);
    let block = i32(gid.z);
    if (x >= IMAGE_W || y >= ROWS) {
        return;
    }
    let pixel = (ROW_FROM + y) * OUT_W + x;
    store_output(block, pixel, vec4f(src[(IN_BLOCK + block) * CANVAS_H * OUT_W + pixel]));
}
