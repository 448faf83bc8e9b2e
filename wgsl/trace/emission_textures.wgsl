// Emission textures (swapped in for trace/emission_plain.wgsl by wgpu_rt/trace/trace_pass.py where a scene's
// lights have one): an emitter's radiance tinted by its mesh's emission texture, sampled as a colour texture is,
// at the point a light sample picks (trace/emitters.wgsl) and where a path meets the light (trace/trace.wgsl).

// #import trace/trace_bindings.wgsl
// #import trace/surface_textures.wgsl

// Emission texture `image` (NO_TEXTURE: none, white) at barycentrics (u, v) of placed triangle `prim`.
fn emission_color(image: u32, prim: u32, u: f32, v: f32) -> vec3f {
    if image == NO_TEXTURE {
        return vec3f(1.0);
    }
    return sample_image(image, record_uv(texture_record(prim), u, v), true);
}

// The colour of placed triangle `prim`'s emission texture at barycentrics (u, v): white where its mesh has none
// (or it has no emitter entry, being too small to have area).
fn triangle_emission_color(prim: u32, u: f32, v: f32) -> vec3f {
    let entry = triangle_emitter[prim];
    if entry == 0u {
        return vec3f(1.0);
    }
    return emission_color(emitters[entry - 1u].emission_image, prim, u, v);
}
