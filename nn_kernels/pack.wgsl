// Planar NCHW f32 (the pipeline's format) → NC4HW4 of the storage type, on a canvas that may be larger
// than the image (the padding the network's pooling needs): the entry conversion where the network's
// first layer does not read the image itself (kernels.PackKernel). The canvas is read as
// load_planar.wgsl describes (edge padding, sanitized). One invocation per canvas pixel and block.
{{ENABLE_F16}}
// #import nn_storage.wgsl
// #import load_planar.wgsl

const IN_H: i32 = {{CANVAS_H}};
const IN_W: i32 = {{CANVAS_W}};
const OUT_BLOCK: i32 = {{OUT_BLOCK}};

@group(0) @binding(1) var<storage, read_write> dst: array<vec4<T>>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3u) {
    let x = i32(gid.x);
    let y = i32(gid.y);
    let block = i32(gid.z);
    if (x >= IN_W || y >= IN_H) {
        return;
    }
    dst[(OUT_BLOCK + block) * IN_H * IN_W + y * IN_W + x] = to_storage(load_input(input_row(block, y), x));
}
