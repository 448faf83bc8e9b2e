// Concat fallback: copy a tensor of CHANNELS channels into channels [OFFSET, OFFSET + CHANNELS) of a
// wider NC4HW4 tensor when OFFSET is not a multiple of 4 (aligned producers write their slice directly
// and need no copy). One invocation per destination pixel and block; it rewrites the whole vec4,
// keeping the channels that belong to the other inputs.
{{ENABLE_F16}}
// #import nn_storage.wgsl

const H: i32 = {{H}};
const W: i32 = {{W}};
const CHANNELS: i32 = {{CHANNELS}};
const OFFSET: i32 = {{OFFSET}};
const IN_BLOCK: i32 = {{IN_BLOCK}};
const OUT_BLOCK: i32 = {{OUT_BLOCK}};
const FIRST_BLOCK: i32 = OFFSET / 4;

@group(0) @binding(0) var<storage, read> src: array<vec4<T>>;
@group(0) @binding(1) var<storage, read_write> dst: array<vec4<T>>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3u) {
    let x = i32(gid.x);
    let y = i32(gid.y);
    let block = FIRST_BLOCK + i32(gid.z);
    if (x >= W || y >= H) {
        return;
    }
    let pixel = y * W + x;
    let out_index = (OUT_BLOCK + block) * H * W + pixel;
    var value = dst[out_index];
    for (var k = 0; k < 4; k++) {
        let channel = block * 4 + k - OFFSET;
        if (channel >= 0 && channel < CHANNELS) {
            value[k] = src[(IN_BLOCK + channel / 4) * H * W + pixel][channel % 4];
        }
    }
    dst[out_index] = value;
}
