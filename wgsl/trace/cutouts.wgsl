// Cut-out surfaces (leaves, fences, lace): a triangle whose texture record carries CUTOUT_FLAG is not there
// wherever its texture's alpha, sampled bilinearly at the point's coordinates, is below one half (a glTF
// MASK material's alpha is shifted at loading so that its alphaCutoff falls there: wgpu_rt/scene/meshio.py);
// with BLEND_FLAG as well (glTF's BLEND) a point is there with probability alpha, decided by a hash of the
// point (its triangle and barycentrics), so that rays through a pixel see a share alpha of the surface: the
// stochastic transparency of Mitsuba's mask. The walks test it for every triangle a ray would otherwise hit,
// closest-hit and shadow rays alike, so light and paths pass through the holes. Swapped in for
// accel/cutouts_none.wgsl by wgpu_rt/trace/trace_pass.py.

// #import trace/texture_images.wgsl
// #import trace/sampling.wgsl

const CUTOUT_ALPHA: f32 = 0.5;
const HAS_CUTOUTS: bool = true;

fn triangle_cut_away(stored: u32, u: f32, v: f32) -> bool {
    let record = surface_textures[0] + TEXTURE_RECORD_WORDS * stored;
    let texture = surface_textures[record];
    if texture == NO_TEXTURE || (texture & CUTOUT_FLAG) == 0u {
        return false;
    }
    let alpha = sample_alpha(texture & TEXTURE_INDEX_MASK, record_uv(record, u, v));
    if (texture & BLEND_FLAG) != 0u {
        let h = hash_combine(hash_combine(bitcast<u32>(u), bitcast<u32>(v)), stored);
        return f32(h >> 8u) * (1.0 / 16777216.0) >= alpha;
    }
    return alpha < CUTOUT_ALPHA;
}
