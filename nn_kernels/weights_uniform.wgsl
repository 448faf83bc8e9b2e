// Weight blocks read directly (no subgroups): a uniform block when the window fits, else storage.
@group(0) @binding({{WEIGHT_BINDING}}) var<{{WEIGHT_SPACE}}> {{WEIGHT}}s: array<mat4x4f, {{WEIGHT_MATS}}>;

fn {{WEIGHT}}_block(index: i32, lane: WeightLane) -> mat4x4f {
    return {{WEIGHT}}s[index];
}
