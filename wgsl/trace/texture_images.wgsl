// The surface-texture buffer's images (bind group 1, binding 5; its layout: trace/surface_textures.wgsl):
// reading a triangle record's coordinates and an image's texels, bilinearly, without the geometry's
// modules, so that trace/cutouts.wgsl can sit inside the walks.

@group(1) @binding(5) var<storage, read> surface_textures: array<u32>;

const NO_TEXTURE: u32 = 0xffffffffu;        // == wgpu_rt.accel.geometry.NO_TEXTURE
const NO_MAP: u32 = 0xffffu;                // == wgpu_rt.accel.geometry.NO_MAP (a record's maps' halves)
const TEXTURE_RECORD_WORDS: u32 = 8u;       // == wgpu_rt.accel.geometry.TEXTURE_RECORD_WORDS
const TEXTURE_HEADER_WORDS: u32 = 4u;       // == wgpu_rt.trace.scene_data.TEXTURE_HEADER_WORDS
const TEXTURE_ENTRY_WORDS: u32 = 4u;        // == wgpu_rt.trace.scene_data.TEXTURE_ENTRY_WORDS
const CUTOUT_FLAG: u32 = 0x80000000u;       // == wgpu_rt.accel.geometry.CUTOUT_FLAG (never on NO_TEXTURE)
const BLEND_FLAG: u32 = 0x40000000u;        // == wgpu_rt.accel.geometry.BLEND_FLAG (with CUTOUT_FLAG)
const TEXTURE_INDEX_MASK: u32 = 0x3fffffffu;   // a record's texture word without its flags

fn texture_uv(record: u32, k: u32) -> vec2f {
    return vec2f(bitcast<f32>(surface_textures[record + 1u + 2u * k]),
                 bitcast<f32>(surface_textures[record + 2u + 2u * k]));
}

fn record_uv(record: u32, u: f32, v: f32) -> vec2f {
    return (1.0 - u - v) * texture_uv(record, 0u) + u * texture_uv(record, 1u) + v * texture_uv(record, 2u);
}

// The four texel words a bilinear sample of image `image` at coordinates `uv` blends, and its weights across
// and down.
struct Footprint {
    top_left: u32,
    top_right: u32,
    bottom_left: u32,
    bottom_right: u32,
    weight: vec2f,
}

// Texel (column, row) of the image whose texels start at `first`, both wrapped into the image.
fn texel_word(first: u32, size: vec2i, column: i32, row: i32) -> u32 {
    let wrapped = (vec2i(column, row) % size + size) % size;
    return surface_textures[first + u32(wrapped.y * size.x + wrapped.x)];
}

fn footprint(image: u32, uv: vec2f) -> Footprint {
    let entry = TEXTURE_HEADER_WORDS + TEXTURE_ENTRY_WORDS * image;
    let first = surface_textures[entry];
    let size = vec2i(i32(surface_textures[entry + 1u]), i32(surface_textures[entry + 2u]));
    let position = vec2f(fract(uv.x), fract(1.0 - uv.y)) * vec2f(size) - 0.5;
    let corner = floor(position);
    let x = i32(corner.x);
    let y = i32(corner.y);
    return Footprint(texel_word(first, size, x, y), texel_word(first, size, x + 1, y),
                     texel_word(first, size, x, y + 1), texel_word(first, size, x + 1, y + 1), position - corner);
}

// Image `image`'s alpha at coordinates `uv`, bilinearly (numpy reference: wgpu_rt.scene.model.sample_alpha).
fn sample_alpha(image: u32, uv: vec2f) -> f32 {
    let f = footprint(image, uv);
    let top = mix(unpack4x8unorm(f.top_left).w, unpack4x8unorm(f.top_right).w, f.weight.x);
    let bottom = mix(unpack4x8unorm(f.bottom_left).w, unpack4x8unorm(f.bottom_right).w, f.weight.x);
    return mix(top, bottom, f.weight.y);
}
