// Cut-out surfaces (leaves, fences, lace): a triangle whose texture record carries CUTOUT_FLAG is not there
// wherever its texture's alpha, sampled bilinearly at the point's coordinates, is below one half (a glTF
// MASK material's alpha is shifted at loading so that its alphaCutoff falls there: wgpu_rt/scene/meshio.py).
// The walks test it for every triangle a ray would otherwise hit, closest-hit and shadow rays alike, so light
// and paths pass through the holes. Swapped in for accel/cutouts_none.wgsl by wgpu_rt/trace/trace_pass.py.

// #import trace/texture_images.wgsl

const CUTOUT_ALPHA: f32 = 0.5;

fn triangle_cut_away(stored: u32, u: f32, v: f32) -> bool {
    let record = surface_textures[0] + TEXTURE_RECORD_WORDS * stored;
    let texture = surface_textures[record];
    if texture == NO_TEXTURE || (texture & CUTOUT_FLAG) == 0u {
        return false;
    }
    return sample_alpha(texture & ~CUTOUT_FLAG, record_uv(record, u, v)) < CUTOUT_ALPHA;
}
