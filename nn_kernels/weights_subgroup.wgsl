// Weight blocks fetched cooperatively: every lane of a subgroup needs the same mat4x4 (16 floats), so
// the lanes split its loads and broadcast the values. With 8 or more lanes, lane k < 8 loads floats
// 2k and 2k + 1 (two scalar loads per lane); with 4 (WebGPU's minimum), lane k loads column k.
// SUBGROUP_LANES is a constant of the pipeline, so only one branch is compiled. On lavapipe a load
// from a uniform block is a vector gather and one from storage a loop over the lanes, so the window is
// a uniform block when it fits, else read-only storage (conv3x3 on lavapipe: ≈ 1.28× the GFLOP/s of
// one vec4 storage load per lane). Call from uniform control flow only. {{WEIGHT}}_block reads block
// `index` of its window, which starts at block {{WINDOW_BASE}} of the binding {{WEIGHTS}} (weight_binding.wgsl).

fn {{WEIGHT}}_block(index: i32, lane: WeightLane) -> mat4x4f {
    if (SUBGROUP_LANES >= 8u) {
        let column = (lane.id % 8u) / 2u;
        let row = (lane.id % 2u) * 2u;
        let a = {{WEIGHTS}}[{{WINDOW_BASE}} + index][column][row];
        let b = {{WEIGHTS}}[{{WINDOW_BASE}} + index][column][row + 1u];
        return mat4x4f(subgroupBroadcast(a, 0u), subgroupBroadcast(b, 0u), subgroupBroadcast(a, 1u),
                       subgroupBroadcast(b, 1u), subgroupBroadcast(a, 2u), subgroupBroadcast(b, 2u),
                       subgroupBroadcast(a, 3u), subgroupBroadcast(b, 3u), subgroupBroadcast(a, 4u),
                       subgroupBroadcast(b, 4u), subgroupBroadcast(a, 5u), subgroupBroadcast(b, 5u),
                       subgroupBroadcast(a, 6u), subgroupBroadcast(b, 6u), subgroupBroadcast(a, 7u),
                       subgroupBroadcast(b, 7u));
    }
    let column = {{WEIGHTS}}[{{WINDOW_BASE}} + index][lane.id % 4u];
    return mat4x4f(subgroupBroadcast(column, 0u), subgroupBroadcast(column, 1u),
                   subgroupBroadcast(column, 2u), subgroupBroadcast(column, 3u));
}
