// Elementwise ops on NC4HW4 tensors, one invocation per pixel and channel block:
// out = activate(a OP b) where OPERAND selects b: 0 none (activation only), 1 a tensor of the same
// shape, 2 a constant per channel (an ONNX initializer broadcast over H and W); OP 0 add, 1 multiply.
{{ENABLE_F16}}
// #import nn_storage.wgsl
// #import nn_activation.wgsl

const H: i32 = {{H}};
const W: i32 = {{W}};
const A_BLOCK: i32 = {{A_BLOCK}};
const B_BLOCK: i32 = {{B_BLOCK}};
const OUT_BLOCK: i32 = {{OUT_BLOCK}};
const OPERAND: u32 = {{OPERAND}}u;
const OP: u32 = {{OP}}u;

@group(0) @binding(0) var<storage, read> a: array<vec4<T>>;
@group(0) @binding(1) var<storage, read_write> dst: array<vec4<T>>;
@group(0) @binding(2) var<storage, read> b_tensor: array<vec4<T>>;
@group(0) @binding(3) var<storage, read> b_constant: array<vec4f>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3u) {
    let x = i32(gid.x);
    let y = i32(gid.y);
    let block = i32(gid.z);
    if (x >= W || y >= H) {
        return;
    }
    let pixel = y * W + x;
    var value = vec4f(a[(A_BLOCK + block) * H * W + pixel]);
    if (OPERAND != 0u) {
        var operand: vec4f;
        if (OPERAND == 1u) {
            operand = vec4f(b_tensor[(B_BLOCK + block) * H * W + pixel]);
        } else {
            operand = b_constant[block];
        }
        if (OP == 0u) {
            value = value + operand;
        } else {
            value = value * operand;
        }
    }
    dst[(OUT_BLOCK + block) * H * W + pixel] = to_storage(activate(value));
}
