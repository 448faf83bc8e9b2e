// Bind groups 1 (scene shading data and frame parameters) and 2 (output planes) of the path-tracing
// kernel; layouts mirror wgpu_rt/trace/scene_data.py (FrameParams, Material, Emitter records).
// Output planes are planar (channel-major): channel c of pixel i lives at c·pixel_count + i.

// #import trace/shading_tables_storage.wgsl

struct FrameParams {
    camera_origin: vec3f,
    width: u32,
    camera_right: vec3f,      // unit right vector times tan(horizontal half-fov)
    height: u32,
    camera_up: vec3f,         // unit up vector times tan(vertical half-fov)
    seed: u32,
    camera_forward: vec3f,
    max_depth: u32,
    previous_origin: vec3f,   // the previous frame's camera, for motion vectors
    sample_offset: u32,
    previous_right: vec3f,    // unit right vector / tan(horizontal half-fov) of the previous camera
    emitter_count: u32,
    previous_up: vec3f,       // unit up vector / tan(vertical half-fov) of the previous camera
    tile_row_stride: u32,     // tile rows are traced in the order row · stride mod rows (camera.wgsl)
    previous_forward: vec3f,
    background_share: f32,    // the background's share of its emitter group (0: not in the table)
    background: vec3f,
    chunk_start: u32,         // this dispatch takes samples [chunk_start, chunk_start + chunk_size)
    chunk_size: u32,          //   of each pixel's count for this pass
    pass_samples: u32,        // the count each pixel takes in a uniform pass
    emitter_group_count: u32,
    background_group: u32,
    lens_radius: f32,         // the thin lens's aperture radius (0: a pinhole; trace/camera.wgsl)
    focus_distance: f32,      // along camera_forward, to the plane in focus
    environment_turn: vec2f,  // cos, sin of the angle the environment map is turned about +y
    emitter_groups: array<EmitterGroup, 16>,   // wgpu_rt.trace.scene_data.MAX_EMITTER_GROUPS
}

@group(1) @binding(0) var<uniform> params: FrameParams;
// per triangle: 1 + the index of its entry in the emitter table, 0 if it does not emit
@group(1) @binding(3) var<storage, read> triangle_emitter: array<u32>;
@group(1) @binding(4) var<storage, read> sample_counts: array<u32>;      // per pixel (adaptive passes)

@group(2) @binding(0) var<storage, read_write> out_radiance: array<f32>;
@group(2) @binding(1) var<storage, read_write> out_albedo: array<f32>;
@group(2) @binding(2) var<storage, read_write> out_normal: array<f32>;
@group(2) @binding(3) var<storage, read_write> out_depth: array<f32>;
@group(2) @binding(4) var<storage, read_write> out_motion: array<f32>;
@group(2) @binding(5) var<storage, read_write> out_spp: array<u32>;
