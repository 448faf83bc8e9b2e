// A planar plane (CHANNELS planes of the frame's pixels) rewritten pixel by pixel with its channels side
// by side, the (H, W, C) order the host hands out, so that reading a frame back is one contiguous copy
// instead of a strided one per channel (frame/interleave.py; numpy reference: `interleaved`).
// #import frame/common.wgsl

override CHANNELS: u32;

@group(0) @binding(0) var<storage, read> planar: array<f32>;
@group(0) @binding(1) var<storage, read_write> interleaved: array<f32>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let pixel = pixel_index(id);
    for (var channel = 0u; channel < CHANNELS; channel++) {
        interleaved[pixel * CHANNELS + channel] = planar[channel * pixel_count() + pixel];
    }
}
