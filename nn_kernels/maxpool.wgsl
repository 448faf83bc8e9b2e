// 2×2 stride-2 max pooling on NC4HW4 tensors (floor mode: a trailing odd row/column is dropped).
// One invocation per output pixel and channel block; max is taken in the storage type.
{{ENABLE_F16}}
// #import nn_storage.wgsl

const IN_H: i32 = {{IN_H}};
const IN_W: i32 = {{IN_W}};
const IN_BLOCK: i32 = {{IN_BLOCK}};
const OUT_H: i32 = {{OUT_H}};
const OUT_W: i32 = {{OUT_W}};
const OUT_BLOCK: i32 = {{OUT_BLOCK}};

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
    let top = (IN_BLOCK + block) * IN_H * IN_W + 2 * y * IN_W + 2 * x;
    let bottom = top + IN_W;
    let pooled = max(max(src[top], src[top + 1]), max(src[bottom], src[bottom + 1]));
    dst[(OUT_BLOCK + block) * OUT_H * OUT_W + y * OUT_W + x] = pooled;
}
