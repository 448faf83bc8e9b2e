// Colour textures (bind group 1, binding 5; laid out by wgpu_rt.trace.scene_data.pack_textures): a
// header (where the triangle records start, the texture count), an entry per texture (its first texel's
// word, width, height), a record per stored triangle (its texture, or NO_TEXTURE, and its vertices'
// texture coordinates as f32 bits), then the texels as packed 8-bit sRGB, row 0 the image's top.
// A texture is sampled as Mitsuba's bitmap with bilinear filtering and repeat wrapping: coordinates
// wrapped to [0, 1), v = 1 at the top, texel centres at half-integers, the four texels decoded to linear
// and blended (numpy reference: wgpu_rt.scene.model.sample_texture).

// #import accel/bvh.wgsl

@group(1) @binding(5) var<storage, read> surface_textures: array<u32>;

const NO_TEXTURE: u32 = 0xffffffffu;        // == wgpu_rt.accel.geometry.NO_TEXTURE
const TEXTURE_RECORD_WORDS: u32 = 8u;       // == wgpu_rt.accel.geometry.TEXTURE_RECORD_WORDS
const TEXTURE_HEADER_WORDS: u32 = 4u;       // == wgpu_rt.trace.scene_data.TEXTURE_HEADER_WORDS
const TEXTURE_ENTRY_WORDS: u32 = 4u;        // == wgpu_rt.trace.scene_data.TEXTURE_ENTRY_WORDS

fn texture_uv(record: u32, k: u32) -> vec2f {
    return vec2f(bitcast<f32>(surface_textures[record + 1u + 2u * k]),
                 bitcast<f32>(surface_textures[record + 2u + 2u * k]));
}

// Texel (column, row) of the texture whose texels start at `first`, both wrapped into the image.
fn texel(first: u32, size: vec2i, column: i32, row: i32) -> vec3f {
    let wrapped = (vec2i(column, row) % size + size) % size;
    return srgb8_to_linear(surface_textures[first + u32(wrapped.y * size.x + wrapped.x)]);
}

// The texture colour at barycentrics (u, v) of placed triangle `prim`: white where its mesh has none, or
// the scene has no texture (the buffer is a header alone, its texture count 0: vertex colours only).
fn texture_color(prim: u32, u: f32, v: f32) -> vec3f {
    if surface_textures[1] == 0u {
        return vec3f(1.0);
    }
    let record = surface_textures[0] + TEXTURE_RECORD_WORDS * placed_triangle(prim).stored;
    let texture = surface_textures[record];
    if texture == NO_TEXTURE {
        return vec3f(1.0);
    }
    let uv = (1.0 - u - v) * texture_uv(record, 0u) + u * texture_uv(record, 1u) + v * texture_uv(record, 2u);
    let entry = TEXTURE_HEADER_WORDS + TEXTURE_ENTRY_WORDS * texture;
    let first = surface_textures[entry];
    let size = vec2i(i32(surface_textures[entry + 1u]), i32(surface_textures[entry + 2u]));
    let position = vec2f(fract(uv.x), fract(1.0 - uv.y)) * vec2f(size) - 0.5;
    let corner = floor(position);
    let weight = position - corner;
    let x = i32(corner.x);
    let y = i32(corner.y);
    let top = mix(texel(first, size, x, y), texel(first, size, x + 1, y), weight.x);
    let bottom = mix(texel(first, size, x, y + 1), texel(first, size, x + 1, y + 1), weight.x);
    return mix(top, bottom, weight.y);
}
