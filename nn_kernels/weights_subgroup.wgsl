// Weight blocks fetched cooperatively: every lane of a subgroup needs the same mat4x4, so lane k loads
// column k % 4 (one vec4 load per lane instead of four per lane) and the four columns are broadcast
// from lanes 0..3 (WebGPU subgroups have at least 4 lanes). Call from uniform control flow only.
@group(0) @binding(2) var<storage, read> weights: array<vec4f>;

fn weight_block(index: i32, lane: u32) -> mat4x4f {
    let column = weights[index * 4 + i32(lane % 4u)];
    return mat4x4f(subgroupBroadcast(column, 0u), subgroupBroadcast(column, 1u),
                   subgroupBroadcast(column, 2u), subgroupBroadcast(column, 3u));
}
