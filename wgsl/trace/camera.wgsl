// The pinhole camera: a film position (pixels, x right, y down) to a primary ray, with a box filter
// (the sample is uniform over the pixel, as Mitsuba's box rfilter), and a world point (or, for
// a ray that escaped, a direction) back to the previous frame's film for motion vectors.

// #import trace/trace_bindings.wgsl

const TILE: u32 = 8u;   // a workgroup is TILE × TILE pixels, == wgpu_rt.trace.trace_pass.TILE

// The pixel of invocation `local_index` of workgroup `tile` (it may lie past the image's edge).
fn tile_pixel(tile: vec3u, local_index: u32) -> vec2u {
    return tile.xy * TILE + vec2u(local_index % TILE, local_index / TILE);
}

fn camera_ray_direction(film: vec2f) -> vec3f {
    let ndc = vec2f(2.0 * film.x / f32(params.width) - 1.0, 1.0 - 2.0 * film.y / f32(params.height));
    return normalize(params.camera_forward + ndc.x * params.camera_right + ndc.y * params.camera_up);
}

// Film position in the previous frame of what is seen along `offset` (a point minus the previous
// camera origin, or a bare direction); `film` itself when it lies behind (or beside) that camera.
fn previous_film_position(offset: vec3f, film: vec2f) -> vec2f {
    let z = dot(offset, params.previous_forward);
    if z <= 1e-6 * length(offset) {
        return film;
    }
    let sx = dot(offset, params.previous_right) / z;
    let sy = dot(offset, params.previous_up) / z;
    return vec2f((sx + 1.0) * 0.5 * f32(params.width), (1.0 - sy) * 0.5 * f32(params.height));
}
