// The camera: a film position (pixels, x right, y down) to a primary ray, with a box filter (the sample
// is uniform over the pixel, as Mitsuba's box rfilter), from a pinhole or a thin lens (Mitsuba's
// thinlens), and a world point (or, for a ray that escaped, a direction) back to the previous frame's
// film for motion vectors.

// #import trace/trace_bindings.wgsl
// #import trace/sampling.wgsl

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

struct CameraRay { origin: vec3f, dir: vec3f }

const LENS_STREAM_SALT: u32 = 0x6c656e73u;   // "lens"

// The primary ray through `film` for the sample `sampler` stands at. A thin lens (params.lens_radius > 0)
// starts it at a uniform point of the aperture disc, aimed at where the pinhole's ray meets the plane in
// focus; the point comes from a stream of its own (the sample's index, a key of its own), so a lens
// leaves every other dimension of the sample, and a pinhole's image, as they were.
fn camera_ray(film: vec2f, sampler: ptr<function, Sampler>) -> CameraRay {
    let dir = camera_ray_direction(film);
    if params.lens_radius <= 0.0 {
        return CameraRay(params.camera_origin, dir);
    }
    var lens_sampler = Sampler((*sampler).index, hash_combine((*sampler).key, LENS_STREAM_SALT), 0u);
    let disc = params.lens_radius * square_to_uniform_disk(next_2d(&lens_sampler));
    let origin = params.camera_origin + disc.x * normalize(params.camera_right) + disc.y * normalize(params.camera_up);
    let focus = params.camera_origin + dir * (params.focus_distance / dot(dir, params.camera_forward));
    return CameraRay(origin, normalize(focus - origin));
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
