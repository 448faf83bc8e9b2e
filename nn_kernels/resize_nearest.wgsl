// Nearest-neighbour ×2 upsampling on NC4HW4 tensors: output pixel (y, x) copies input (y/2, x/2).
{{ENABLE_F16}}
// #import nn_storage.wgsl

const IN_H: i32 = {{IN_H}};
const IN_W: i32 = {{IN_W}};
const IN_BLOCK: i32 = {{IN_BLOCK}};
const OUT_BLOCK: i32 = {{OUT_BLOCK}};
const OUT_H: i32 = 2 * IN_H;
const OUT_W: i32 = 2 * IN_W;

@group(0) @binding(0) var<storage, read> src: array<vec4<T>>;
@group(0) @binding(1) var<storage, read_write> dst: array<vec4<T>>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3u) {
    let x = i32(gid.x);
    let y = i32(gid.y);
    let block = i32(gid.z);
    if (x >= OUT_W || y >= OUT_H) {
        return;
    }
    let value = src[(IN_BLOCK + block) * IN_H * IN_W + (y / 2) * IN_W + x / 2];
    dst[(OUT_BLOCK + block) * OUT_H * OUT_W + y * OUT_W + x] = value;
}
