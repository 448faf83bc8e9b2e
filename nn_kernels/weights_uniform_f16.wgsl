// Weight blocks as halves, read directly (weights_uniform.wgsl for half-precision multiply-adds): block
// `index` of the window that starts at block {{WINDOW_BASE}} of the binding {{WEIGHTS}} (always storage:
// kernels.WindowLayout), each 64-byte slot holding the block as a mat4x4<f16> and 32 bytes of padding
// (weight_binding.wgsl). There is no subgroup variant: naga cannot bitcast a word to two halves, so the
// lanes could not share the loads without converting every value.

fn {{WEIGHT}}_block(index: i32, lane: WeightLane) -> mat4x4<f16> {
    return {{WEIGHTS}}[{{WINDOW_BASE}} + index][0];
}
