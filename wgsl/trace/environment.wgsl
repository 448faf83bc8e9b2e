// The sky's radiance along a direction (bind group 1, binding 6; laid out by
// wgpu_rt.trace.scene_data.pack_environment): the constant params.background, or with an environment map
// that per-channel scale times the map, a latitude-longitude image read as Mitsuba's envmap reads it:
// u = atan2(x, -z) / 2π, v = acos(y) / π (+y up), columns centred at u = (j + ½) / W and periodic, rows at
// v = i / (H − 1), bilinear (numpy reference: wgpu_rt.scene.model.sample_environment).
// Directions toward the sky are drawn in proportion to its cells' weights (scene_data.environment_cells:
// the patches between neighbouring texels, by luminance and solid angle), a row by the rows' cumulative
// distribution and then a cell of it by the row's, each inverted continuously, so a small bright sun is
// found by next-event estimation; a constant background (or a black map) is sampled uniformly.

// #import trace/trace_bindings.wgsl
// #import trace/sampling.wgsl
// #import math.wgsl

@group(1) @binding(6) var<storage, read> environment: array<u32>;

const ENVIRONMENT_HEADER_WORDS: u32 = 4u;   // == wgpu_rt.trace.scene_data.ENVIRONMENT_HEADER_WORDS

fn environment_float(at: u32) -> f32 {
    return bitcast<f32>(environment[at]);
}

fn environment_texel(width: u32, column: u32, row: u32) -> vec3f {
    let at = ENVIRONMENT_HEADER_WORDS + 3u * (row * width + column);
    return vec3f(environment_float(at), environment_float(at + 1u), environment_float(at + 2u));
}

// A world direction in the map's own frame (the map turned about +y by params.environment_turn), and back.
fn to_map(dir: vec3f) -> vec3f {
    let turn = params.environment_turn;
    return vec3f(turn.x * dir.x - turn.y * dir.z, dir.y, turn.y * dir.x + turn.x * dir.z);
}

fn from_map(dir: vec3f) -> vec3f {
    let turn = params.environment_turn;
    return vec3f(turn.x * dir.x + turn.y * dir.z, dir.y, turn.x * dir.z - turn.y * dir.x);
}

// Where unit direction `world_dir` falls on a map of `width` columns and `rows` + 1 rows, in texels (x from
// the first column's centre, periodic; y from the top row), and the cell it is in (the texels at its top
// left corner: the four corners the radiance blends, and the cell the sky's sampling draws it in).
struct MapPosition { at: vec2f, cell: vec2u }

fn map_position(world_dir: vec3f, width: u32, rows: u32) -> MapPosition {
    let dir = to_map(world_dir);
    let u = atan2(dir.x, -dir.z) * (0.5 / PI);
    let v = acos(clamp(dir.y, -1.0, 1.0)) / PI;
    let at = vec2f(fract(u - 0.5 / f32(width)) * f32(width), v * f32(rows));
    return MapPosition(at, min(vec2u(at), vec2u(width - 1u, rows - 1u)));
}

// Radiance arriving from the sky along unit direction `world_dir` (the direction a ray travels).
fn background_radiance(world_dir: vec3f) -> vec3f {
    let width = environment[0];
    if width == 0u {
        return params.background;
    }
    let position = map_position(world_dir, width, environment[1] - 1u);
    let x0 = position.cell.x;
    let y0 = position.cell.y;
    let weight = position.at - vec2f(position.cell);
    let x1 = (x0 + 1u) % width;
    let top = mix(environment_texel(width, x0, y0), environment_texel(width, x1, y0), weight.x);
    let bottom = mix(environment_texel(width, x0, y0 + 1u), environment_texel(width, x1, y0 + 1u), weight.x);
    return params.background * mix(top, bottom, weight.y);
}

// Whether sky directions are drawn uniformly: a constant background, or a map with no weight (black).
fn sky_is_uniform() -> bool {
    return environment[0] == 0u || environment_float(2u) <= 0.0;
}

// The first of the `count` increasing values from word `first` on that exceeds x (the last if none does).
fn first_above(first: u32, count: u32, x: f32) -> u32 {
    var low = 0u;
    var high = count - 1u;
    while low < high {
        let middle = (low + high) / 2u;
        if environment_float(first + middle) > x {
            high = middle;
        } else {
            low = middle + 1u;
        }
    }
    return low;
}

// Where the cells' weights and the two cumulative distributions start (pack_environment's order).
struct SkyTables { width: u32, rows: u32, total: f32, cells: u32, row_cdf: u32, within: u32 }

fn sky_tables() -> SkyTables {
    let width = environment[0];
    let rows = environment[1] - 1u;
    let cells = ENVIRONMENT_HEADER_WORDS + 3u * width * (rows + 1u);
    return SkyTables(width, rows, environment_float(2u), cells, cells + width * rows, cells + width * rows + rows);
}

// Solid-angle pdf of drawing a direction in `cell` at polar angle sine `sin_theta`.
fn sky_cell_pdf(t: SkyTables, cell: u32, sin_theta: f32) -> f32 {
    return environment_float(t.cells + cell) / t.total * f32(t.width * t.rows) / (2.0 * PI * PI * max(sin_theta, 1e-7));
}

struct SkySample { dir: vec3f, pdf: f32 }   // pdf per unit solid angle

// A direction toward the sky from two uniform numbers, with its solid-angle pdf.
fn sample_sky(u: vec2f) -> SkySample {
    if sky_is_uniform() {
        return SkySample(square_to_uniform_sphere(u), INV_FOUR_PI);
    }
    let t = sky_tables();
    let row = first_above(t.row_cdf, t.rows, u.y);
    let row_low = select(0.0, environment_float(t.row_cdf + row - 1u), row > 0u);
    let row_share = environment_float(t.row_cdf + row) - row_low;
    let along_v = clamp((u.y - row_low) / max(row_share, 1e-30), 0.0, 1.0);
    let row_first = t.within + row * t.width;
    let column = first_above(row_first, t.width, u.x);
    let column_low = select(0.0, environment_float(row_first + column - 1u), column > 0u);
    let column_share = environment_float(row_first + column) - column_low;
    let along_u = clamp((u.x - column_low) / max(column_share, 1e-30), 0.0, 1.0);
    let theta = PI * (f32(row) + along_v) / f32(t.rows);
    let phi = 2.0 * PI * (f32(column) + along_u + 0.5) / f32(t.width);   // cells start half a texel on
    let sin_theta = sin(theta);
    let dir = vec3f(sin(phi) * sin_theta, cos(theta), -cos(phi) * sin_theta);
    return SkySample(from_map(dir), sky_cell_pdf(t, row * t.width + column, sin_theta));
}

// The solid-angle pdf with which sample_sky draws unit direction `world_dir`.
fn sky_pdf(world_dir: vec3f) -> f32 {
    if sky_is_uniform() {
        return INV_FOUR_PI;
    }
    let t = sky_tables();
    let cell = map_position(world_dir, t.width, t.rows).cell;
    return sky_cell_pdf(t, cell.y * t.width + cell.x, length(world_dir.xz));   // sin θ: the turn keeps y
}
