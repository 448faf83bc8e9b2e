// Weight blocks read directly (no subgroups): a uniform block when the window fits, else storage.
@group(0) @binding(2) var<{{WEIGHT_SPACE}}> weights: array<mat4x4f, {{WEIGHT_MATS}}>;

fn weight_block(index: i32, lane: u32) -> mat4x4f {
    return weights[index];
}
