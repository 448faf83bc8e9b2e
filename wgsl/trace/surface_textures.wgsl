// Colour textures and maps (bind group 1, binding 5; laid out by wgpu_rt.trace.scene_data.pack_textures): a header
// (where the triangle records start, the image count), an entry per image (its first texel's word, width, height,
// a metal-rough map's coat levels' first word), a record per stored triangle (its texture, or NO_TEXTURE, with
// CUTOUT_FLAG where the texture's alpha cuts the surface away and BLEND_FLAG where it does so stochastically,
// trace/cutouts.wgsl; its vertices' texture coordinates as f32 bits; its normal map in the low half of a word and
// its metal-rough map in the high half, each NO_MAP where it has none: trace/metal_rough_maps.wgsl), then the
// texels as packed 8-bit codes (alpha, where an image has one, in the top byte), row 0 the image's top. An image is
// sampled as Mitsuba's bitmap with bilinear filtering and repeat wrapping: coordinates wrapped to [0, 1), v = 1 at
// the top, texel centres at half-integers, the four texels decoded (a texture's from sRGB, a map's raw) and blended
// (numpy reference: wgpu_rt.scene.model.sample_texture; a normal map's tilt: mapped_normal).

// #import accel/bvh.wgsl
// #import trace/texture_images.wgsl

// The first word of placed triangle `prim`'s record.
fn texture_record(prim: u32) -> u32 {
    return surface_textures[0] + TEXTURE_RECORD_WORDS * placed_triangle(prim).stored;
}

// A texel word's colour: decoded from sRGB to linear where `srgb`, else read raw (code / 255).
fn texel_color(word: u32, srgb: bool) -> vec3f {
    return select(unpack4x8unorm(word).xyz, srgb8_to_linear(word), srgb);
}

// Image `image` at coordinates `uv`, bilinearly.
fn sample_image(image: u32, uv: vec2f, srgb: bool) -> vec3f {
    let f = footprint(image, uv);
    let top = mix(texel_color(f.top_left, srgb), texel_color(f.top_right, srgb), f.weight.x);
    let bottom = mix(texel_color(f.bottom_left, srgb), texel_color(f.bottom_right, srgb), f.weight.x);
    return mix(top, bottom, f.weight.y);
}

// The texture colour at barycentrics (u, v) of placed triangle `prim`: white where its mesh has none, or
// the scene has no image (the buffer is a header alone, its image count 0: vertex colours only).
fn texture_color(prim: u32, u: f32, v: f32) -> vec3f {
    if surface_textures[1] == 0u {
        return vec3f(1.0);
    }
    let record = texture_record(prim);
    let texture = surface_textures[record];
    if texture == NO_TEXTURE {
        return vec3f(1.0);
    }
    return sample_image(texture & TEXTURE_INDEX_MASK, record_uv(record, u, v), true);
}

// The unit shading normal `normal` at barycentrics (u, v) of placed triangle `prim` tilted by its mesh's
// normal map, as Mitsuba's normalmap: 2·texel − 1 in the frame of `normal`, the surface's direction of
// increasing u (from the triangle's world vertices and coordinates) made perpendicular to it, and their
// cross product. Unchanged where the mesh has no normal map or its coordinates do not span the triangle.
fn normal_mapped(prim: u32, u: f32, v: f32, normal: vec3f) -> vec3f {
    if surface_textures[1] == 0u {
        return normal;
    }
    let record = texture_record(prim);
    let map = surface_textures[record + 7u] & NO_MAP;
    if map == NO_MAP {
        return normal;
    }
    let p = tri_vertices(prim);
    let duv0 = texture_uv(record, 1u) - texture_uv(record, 0u);
    let duv1 = texture_uv(record, 2u) - texture_uv(record, 0u);
    let det = duv0.x * duv1.y - duv0.y * duv1.x;
    // dp/du up to the positive factor 1 / |det|: only its direction is used.
    let dp_du = sign(det) * (duv1.y * (p[1] - p[0]) - duv0.y * (p[2] - p[0]));
    let along = dp_du - normal * dot(normal, dp_du);
    let length2 = dot(along, along);
    if !(length2 > 1e-12 * dot(dp_du, dp_du)) || det == 0.0 {
        return normal;
    }
    let s = along * inverseSqrt(length2);
    let local = 2.0 * sample_image(map, record_uv(record, u, v), false) - 1.0;
    let mapped = local.x * s + local.y * cross(normal, s) + local.z * normal;
    let mapped2 = dot(mapped, mapped);
    return select(normal, mapped * inverseSqrt(mapped2), mapped2 > 1e-12);
}
