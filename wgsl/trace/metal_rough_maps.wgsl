// A hit's material as its mesh's metal-rough map makes it (glTF's metallic-roughness texture, its factors applied
// at loading: wgpu_rt.scene.model.Mesh.metal_rough_map). On a conductor the map's roughness (green) is its GGX
// alpha's square root per point and the metalness is not read. On a plastic, at a point of the map's
// roughness r and metalness m (green and blue, raw, bilinearly) the surface is glTF's metal (a conductor of Fresnel
// 1 tinted by the reflectance) with probability m, decided by a hash of the point (its triangle and barycentrics,
// as a blended cut-out's: trace/cutouts.wgsl), else the plastic, either of GGX alpha r²: in expectation glTF's
// blend of the two, as Mitsuba's blendbsdf. The plastic's coat tables are the texture buffer's levels at
// r = i / (COAT_LEVELS − 1) (wgpu_rt/trace/coat.py), each half linearly between the two about r. Swapped in for
// trace/metal_rough_none.wgsl by wgpu_rt/trace/trace_pass.py.

// #import trace/material.wgsl
// #import trace/surface_textures.wgsl
// #import trace/sampling.wgsl

const COAT_LEVELS: u32 = 17u;               // == wgpu_rt.trace.coat.COAT_LEVELS
const COAT_WORDS: u32 = 6u;                 // a coat table's words (a plastic record's eta and k)
const METAL_SALT: u32 = 0x6d657461u;        // keeps the metal's hash apart from a blended cut-out's

// Word `w` of the coat table at roughness level position `x` (in [0, COAT_LEVELS − 1]) of the levels at `first`.
fn coat_word_between(first: u32, x: f32, w: u32) -> f32 {
    let i = min(u32(x), COAT_LEVELS - 2u);
    let below = unpack2x16float(surface_textures[first + COAT_WORDS * i + w]);
    let above = unpack2x16float(surface_textures[first + COAT_WORDS * (i + 1u) + w]);
    return bitcast<f32>(pack2x16float(mix(below, above, x - f32(i))));
}

fn metal_rough_mapped(material: Material, hit: Hit) -> Material {
    if surface_textures[1] == 0u || (material.kind != MATERIAL_PLASTIC && material.kind != MATERIAL_CONDUCTOR) {
        return material;
    }
    let record = texture_record(hit.prim);
    let map = surface_textures[record + 7u] >> 16u;
    if map == NO_MAP {
        return material;
    }
    let texel = sample_image(map, record_uv(record, hit.u, hit.v), false);
    var mapped = material;
    mapped.roughness = texel.y * texel.y;
    if material.kind == MATERIAL_CONDUCTOR {     // a metal of its own everywhere: the map roughens it, no more
        return mapped;
    }
    let h = hash_combine(hash_combine(hash_combine(bitcast<u32>(hit.u), bitcast<u32>(hit.v)), hit.prim), METAL_SALT);
    if f32(h >> 8u) * (1.0 / 16777216.0) < texel.z {
        mapped.kind = MATERIAL_CONDUCTOR;
        mapped.eta = vec3f(0.0);
        mapped.k = vec3f(1.0);
        return mapped;
    }
    let first = surface_textures[TEXTURE_HEADER_WORDS + TEXTURE_ENTRY_WORDS * map + 3u];
    let x = clamp(texel.y, 0.0, 1.0) * f32(COAT_LEVELS - 1u);
    mapped.eta = vec3f(coat_word_between(first, x, 0u), coat_word_between(first, x, 1u),
                       coat_word_between(first, x, 2u));
    mapped.k = vec3f(coat_word_between(first, x, 3u), coat_word_between(first, x, 4u),
                     coat_word_between(first, x, 5u));
    return mapped;
}
