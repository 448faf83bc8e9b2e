// The pinhole camera: a film position (pixels, x right, y down) to a primary ray, with a box filter
// (the sample is uniform over the pixel, as Mitsuba's box rfilter), and a world point (or, for
// a ray that escaped, a direction) back to the previous frame's film for motion vectors.

// #import trace/trace_bindings.wgsl

const TILE: u32 = 8u;   // a workgroup is TILE × TILE pixels, == wgpu_rt.trace.trace_pass.TILE

// The pixel of invocation `local_index` of workgroup `tile` (it may lie past the image's edge).
// Workgroup row y traces tile row y · tile_row_stride mod rows (a stride coprime to the rows, so every
// row once). On CPU drivers the stride is near 0.618 of the rows: such a driver hands each of its
// threads one contiguous range of a dispatch's workgroups, and in image order one thread would get the
// rows where the costly geometry sits while the other waited (on lavapipe the cores were busy 80 % of
// a `cornell-glossy` pass); scattered rows give every range a share of the whole height. On GPUs it is
// 1 (image order): they take workgroups as they free up, and neighbouring tiles share cached nodes.
fn tile_pixel(tile: vec3u, local_index: u32) -> vec2u {
    let rows = (params.height + TILE - 1u) / TILE;
    let row = (tile.y * params.tile_row_stride) % rows;
    return vec2u(tile.x, row) * TILE + vec2u(local_index % TILE, local_index / TILE);
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
