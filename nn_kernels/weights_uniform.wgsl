// Weight blocks read directly (no subgroups): block `index` of the window that starts at block
// {{WINDOW_BASE}} of the binding {{WEIGHTS}} (weight_binding.wgsl).

fn {{WEIGHT}}_block(index: i32, lane: WeightLane) -> mat4x4f {
    return {{WEIGHTS}}[{{WINDOW_BASE}} + index];
}
