// The sky's radiance along a direction (bind group 1, binding 6; laid out by
// wgpu_rt.trace.scene_data.pack_environment): the constant params.background, or with an environment map
// that per-channel scale times the map, a latitude-longitude image read as Mitsuba's envmap reads it:
// u = atan2(x, -z) / 2π, v = acos(y) / π (+y up), columns centred at u = (j + ½) / W and periodic, rows at
// v = i / (H − 1), bilinear (numpy reference: wgpu_rt.scene.model.sample_environment).

// #import trace/trace_bindings.wgsl
// #import math.wgsl

@group(1) @binding(6) var<storage, read> environment: array<u32>;

const ENVIRONMENT_HEADER_WORDS: u32 = 4u;   // == wgpu_rt.trace.scene_data.ENVIRONMENT_HEADER_WORDS

fn environment_texel(width: u32, column: u32, row: u32) -> vec3f {
    let at = ENVIRONMENT_HEADER_WORDS + 3u * (row * width + column);
    return vec3f(bitcast<f32>(environment[at]), bitcast<f32>(environment[at + 1u]), bitcast<f32>(environment[at + 2u]));
}

// Radiance arriving from the sky along unit direction `dir` (the direction a ray travels).
fn background_radiance(dir: vec3f) -> vec3f {
    let width = environment[0];
    if width == 0u {
        return params.background;
    }
    let height = environment[1];
    let u = atan2(dir.x, -dir.z) * (0.5 / PI);
    let v = acos(clamp(dir.y, -1.0, 1.0)) / PI;
    let x = fract(u - 0.5 / f32(width)) * f32(width);
    let y = v * f32(height - 1u);
    let x0 = min(u32(x), width - 1u);
    let y0 = min(u32(y), height - 2u);
    let weight = vec2f(x - f32(x0), y - f32(y0));
    let x1 = (x0 + 1u) % width;
    let top = mix(environment_texel(width, x0, y0), environment_texel(width, x1, y0), weight.x);
    let bottom = mix(environment_texel(width, x0, y0 + 1u), environment_texel(width, x1, y0 + 1u), weight.x);
    return params.background * mix(top, bottom, weight.y);
}
