// Frame max depth, the denoiser's depth normaliser, found on the device so packing needs no CPU round
// trip. Each 8×8 workgroup reduces its sanitised depths in workgroup memory (tree reduction), then one
// invocation folds the tile's maximum into a single u32 with atomicMax: for non-negative floats the
// IEEE-754 bit pattern orders like the value, so the u32 maximum is the float maximum. The caller
// clears `depth_max_bits` to 0 (= 0.0) before the dispatch.
// #import frame/common.wgsl

@group(0) @binding(0) var<storage, read> depth: array<f32>;
@group(0) @binding(1) var<storage, read_write> depth_max_bits: atomic<u32>;

var<workgroup> tile_max: array<f32, 64>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3u, @builtin(local_invocation_index) lane: u32) {
    var d = 0.0;
    if (in_frame(id)) { d = sanitize(depth[pixel_index(id)]); }
    tile_max[lane] = d;
    workgroupBarrier();
    for (var stride = 32u; stride > 0u; stride = stride >> 1u) {
        if (lane < stride) { tile_max[lane] = max(tile_max[lane], tile_max[lane + stride]); }
        workgroupBarrier();
    }
    if (lane == 0u) { atomicMax(&depth_max_bits, bitcast<u32>(tile_max[0])); }
}
