// Temporal accumulation of the denoised frame (after TAA/SVGF). History holds 8 planes: RGB, depth,
// normal xyz and history length (frames accumulated; 0 = empty).
//   reproject:  each pixel looks up where it was last frame (its position plus its motion vector) and
//               takes a bilinear history sample from the 4 surrounding texels, keeping only texels that
//               pass the disocclusion tests (relative depth difference ≤ DEPTH_TOLERANCE, normal
//               dot ≥ NORMAL_THRESHOLD; sky matches only sky) and renormalising their weights. No valid
//               texel → length 0 (disoccluded). Writes 5 planes: RGB, previous depth, length.
//   blend:      history is clamped to the current 3×3 neighbourhood (CLAMP_MODE 1: min/max box;
//               2: variance rectification, mean ± GAMMA·σ), then out = mix(history, current, α) with
//               α = mix(1, 0.01, confidence) when the confidence predictor ran (confidence = trust in the
//               history: the network output c ramped linearly from 0 at CONFIDENCE_FLOOR to 1 at 1; it
//               is trained with class-balanced weights, so its low outputs are not probabilities but
//               "disoccluded", and keep no history), else 1/(length+1); α ≥ 1/MAX_FRAMES, and α = 1 where
//               disoccluded.
//   accumulate: static camera and scene: no reprojection or clamping, α = max(1/(length+1), 1/MAX_FRAMES)
//               per pixel (a cleared history, length 0, makes it a reset).
//   converge:   static view whose tracer planes keep accumulating (the frame pipeline's temporal mode):
//               the colour given is the converge pass's blend of the n-sample mean and its denoised
//               frame (frame/converge.wgsl); it replaces the history (length 1).
// Every path writes the output plane and the new history; NaN/Inf in the current frame count as 0.
// #import frame/common.wgsl

override CLAMP_MODE: u32 = 2u;
override GAMMA: f32 = 1.0;
override MAX_FRAMES: f32 = 32.0;
override DEPTH_TOLERANCE: f32 = 0.05;
override NORMAL_THRESHOLD: f32 = 0.9;
override USE_CONFIDENCE: bool = false;
override CONFIDENCE_FLOOR: f32 = 0.3;

@group(0) @binding(0) var<storage, read> color: array<f32>;
@group(0) @binding(1) var<storage, read> depth: array<f32>;
@group(0) @binding(2) var<storage, read> normal: array<f32>;
@group(0) @binding(3) var<storage, read> motion: array<f32>;
@group(0) @binding(4) var<storage, read_write> history: array<f32>;
@group(0) @binding(5) var<storage, read_write> reprojected: array<f32>;
@group(0) @binding(6) var<storage, read> confidence: array<f32>;
@group(0) @binding(7) var<storage, read_write> output: array<f32>;

fn current_color(i: u32) -> vec3f {
    let n = pixel_count();
    return vec3f(sanitize(color[i]), sanitize(color[n + i]), sanitize(color[2u * n + i]));
}

fn current_normal(i: u32) -> vec3f {
    let n = pixel_count();
    return vec3f(finite_or_zero(normal[i]), finite_or_zero(normal[n + i]), finite_or_zero(normal[2u * n + i]));
}

fn history_plane(plane: u32, i: u32) -> f32 { return history[plane * pixel_count() + i]; }

fn surfaces_match(i_history: u32, current_depth: f32, n_current: vec3f) -> bool {
    let previous_depth = history_plane(3u, i_history);
    if (current_depth <= 0.0 || previous_depth <= 0.0) { return current_depth <= 0.0 && previous_depth <= 0.0; }
    if (abs(previous_depth - current_depth) > DEPTH_TOLERANCE * current_depth) { return false; }
    let n_previous = vec3f(history_plane(4u, i_history), history_plane(5u, i_history), history_plane(6u, i_history));
    return dot(n_previous, n_current) >= NORMAL_THRESHOLD;
}

fn write_result(i: u32, value: vec3f, length: f32) {
    let n = pixel_count();
    let normal_now = current_normal(i);
    for (var c = 0u; c < 3u; c++) {
        output[c * n + i] = value[c];
        history[c * n + i] = value[c];
        history[(4u + c) * n + i] = normal_now[c];
    }
    history[3u * n + i] = sanitize(depth[i]);
    history[7u * n + i] = length;
}

@compute @workgroup_size(8, 8)
fn reproject(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    let n = pixel_count();
    let d = sanitize(depth[i]);
    let n_current = current_normal(i);
    let m = vec2f(motion[i], motion[n + i]);
    var sum = vec4f(0.0);   // RGB, depth
    var length = 0.0;
    var weight = 0.0;
    if (is_finite(m.x) && is_finite(m.y)) {
        let previous = vec2f(f32(id.x), f32(id.y)) + m;   // texel-centre coordinates
        let base = floor(previous);
        let f = previous - base;
        for (var tap = 0u; tap < 4u; tap++) {
            let offset = vec2u(tap & 1u, tap >> 1u);
            let w = select(1.0 - f.x, f.x, offset.x == 1u) * select(1.0 - f.y, f.y, offset.y == 1u);
            let texel = vec2i(base) + vec2i(offset);
            if (w <= 0.0 || texel.x < 0 || texel.y < 0 || texel.x >= i32(WIDTH) || texel.y >= i32(HEIGHT)) {
                continue;
            }
            let j = u32(texel.y) * WIDTH + u32(texel.x);
            if (history_plane(7u, j) <= 0.0 || !surfaces_match(j, d, n_current)) { continue; }
            sum += w * vec4f(history_plane(0u, j), history_plane(1u, j), history_plane(2u, j), history_plane(3u, j));
            length += w * history_plane(7u, j);
            weight += w;
        }
    }
    let valid = weight > 1e-3;
    let inverse = select(0.0, 1.0 / weight, valid);
    for (var c = 0u; c < 4u; c++) { reprojected[c * n + i] = sum[c] * inverse; }
    reprojected[4u * n + i] = length * inverse;
}

fn clamp_to_neighbourhood(id: vec3u, value: vec3f) -> vec3f {
    var low = vec3f(3.0e38);
    var high = vec3f(0.0);
    var mean = vec3f(0.0);
    var mean_square = vec3f(0.0);
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let x = u32(clamp(i32(id.x) + dx, 0, i32(WIDTH) - 1));
            let y = u32(clamp(i32(id.y) + dy, 0, i32(HEIGHT) - 1));
            let c = current_color(y * WIDTH + x);
            low = min(low, c);
            high = max(high, c);
            mean += c / 9.0;
            mean_square += c * c / 9.0;
        }
    }
    if (CLAMP_MODE == 2u) {
        let sigma = sqrt(max(mean_square - mean * mean, vec3f(0.0)));
        low = max(mean - GAMMA * sigma, vec3f(0.0));
        high = mean + GAMMA * sigma;
    }
    return clamp(value, low, high);
}

@compute @workgroup_size(8, 8)
fn blend(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    let n = pixel_count();
    let current = current_color(i);
    let length = reprojected[4u * n + i];
    if (length <= 0.0) {
        write_result(i, current, 1.0);
        return;
    }
    var previous = vec3f(reprojected[i], reprojected[n + i], reprojected[2u * n + i]);
    if (CLAMP_MODE != 0u) { previous = clamp_to_neighbourhood(id, previous); }
    var alpha = 1.0 / (length + 1.0);
    if (USE_CONFIDENCE) {
        let c = clamp(finite_or_zero(confidence[i]), 0.0, 1.0);
        let trust = max(c - CONFIDENCE_FLOOR, 0.0) / (1.0 - CONFIDENCE_FLOOR);
        alpha = mix(1.0, 0.01, trust);
    }
    alpha = max(alpha, 1.0 / MAX_FRAMES);
    write_result(i, mix(previous, current, alpha), min(length + 1.0, MAX_FRAMES));
}

@compute @workgroup_size(8, 8)
fn accumulate(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    let n = pixel_count();
    let length = history_plane(7u, i);
    let alpha = max(1.0 / (length + 1.0), 1.0 / MAX_FRAMES);
    let previous = vec3f(history_plane(0u, i), history_plane(1u, i), history_plane(2u, i));
    write_result(i, mix(previous, current_color(i), alpha), min(length + 1.0, MAX_FRAMES));
}

@compute @workgroup_size(8, 8)
fn converge(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    write_result(i, current_color(i), 1.0);
}
