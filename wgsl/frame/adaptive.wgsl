// Adaptive sampling: turns a per-pixel importance (the error predictor's heatmap in [0, 1], a
// half-buffer error estimate, or a constant) into the u32 plane of extra samples the targeted tracer
// pass takes.
//   extra_from_heat: extra = floor(heat^K · 31), heat clamped to [0, 1].
//   budget (exact total TARGET extra samples, at most CAP per pixel), deterministic (same importance →
//   same counts, bit for bit: only integer atomics and fixed-order reductions, no race decides anything):
//     square_importance: p = max(importance, 0)^K; squared = p².
//     weigh:          w = sqrt(p² + P), P the Gaussian-weighted mean of p² over the pixel's
//                     neighbourhood (standard deviation POOL_SIGMA px, taps within POOL_RADIUS, the
//                     weights renormalised over the taps inside the frame); P = 0 when POOL_RADIUS = 0,
//                     so w = p. p² is one probe's squared error, its local mean the per-sample error
//                     variance one probe cannot tell (frame/adaptive.py, AdaptiveSettings.pool_sigma).
//                     Per-8×8-tile sums of w → tile_sums.
//     sum_weights:    one workgroup adds the tile sums → budget.weight_sum.
//     assign:         ideal = EVENLY_SPREAD·TARGET/N + (1 − EVENLY_SPREAD)·w·TARGET/Σw (a defensive
//                     mixture; TARGET/N when Σw = 0, all of it when EVENLY_SPREAD = 1: the uniform
//                     sampler); extra = min(floor(ideal), CAP);
//                     the fractional part is kept as the pixel's claim on the remainder (−1 if capped).
//     then rounds of three kernels hand out the remainder R = TARGET − Σextra, one sample per pixel per
//     round. Candidates are pixels below CAP whose claim ≥ THRESHOLD, ranked in scan order (tile by
//     tile, row-major inside a tile):
//       count_candidates: per-tile candidate counts → tile_offsets.
//       scan_candidates:  one workgroup turns the counts into exclusive prefix offsets, giving the total
//                         C; the round hands out q = min(R, C) (budget.quota, budget.candidates).
//       take:             a candidate of rank r takes one sample iff q = C or (r·q mod C) + q ≥ C, i.e.
//                         floor((r+1)q/C) > floor(rq/C): exactly q samples, spread evenly over the scan
//                         order (so over the image) rather than bunched at its top.
//     Rounds with THRESHOLD 0.5 then 0 round claims up, larger first; later rounds (THRESHOLD −2) let
//     any pixel below CAP take one more until the budget is met (what capped pixels could not take).
//     Those spill rounds are dispatched indirectly: each scan writes the workgroup counts of the next
//     spill round (slot NEXT_SLOT of spill_args), zero once the budget is met or a spill round found
//     nothing to hand out (then every later one would find nothing too). So the usual frame, where no
//     pixel is capped, pays for no spill round at all.
//   half_buffer_error: Cycles' estimate from the mean of all samples I and of the first half A:
//                     Σ|I − A| / (1e-4 + sqrt(ΣI)) (the variance-based baseline's importance).
// #import frame/common.wgsl
// #import trace/workgroup_scan.wgsl

override K: f32 = 3.0;
override EVENLY_SPREAD: f32 = 0.0;
override TARGET: u32 = 0u;
override CAP: u32 = 31u;
override THRESHOLD: f32 = 0.5;
override NEXT_SLOT: u32 = 0u;
override POOL_SIGMA: f32 = 1.0;   // read only when POOL_RADIUS > 0
override POOL_RADIUS: i32 = 0;

struct Budget {
    weight_sum: f32,
    assigned: atomic<u32>,   // extra samples given so far
    quota: u32,              // samples the current round hands out
    candidates: u32,         // candidates of the current round
}

@group(0) @binding(0) var<storage, read> source: array<f32>;   // importance, or full radiance
@group(0) @binding(1) var<storage, read_write> extra: array<u32>;
@group(0) @binding(2) var<storage, read_write> claim: array<f32>;
@group(0) @binding(3) var<storage, read_write> tile_sums: array<f32>;
@group(0) @binding(4) var<storage, read_write> budget: Budget;
@group(0) @binding(5) var<storage, read> half_radiance: array<f32>;
@group(0) @binding(6) var<storage, read_write> error: array<f32>;
@group(0) @binding(7) var<storage, read_write> tile_offsets: array<u32>;
// Per spill round: (x, y, z) workgroups of its count and take kernels, then (x, y, z) of its scan.
@group(0) @binding(8) var<storage, read_write> spill_args: array<u32>;
@group(0) @binding(9) var<storage, read_write> squared: array<f32>;   // p² of square_importance

var<workgroup> partial: array<f32, 64>;

// The sum of partial[0..64) into partial[0] (tree order, so the same values give the same bits); every
// lane of the workgroup calls it after writing partial[lane].
fn sum_partial(lane: u32) {
    workgroupBarrier();
    for (var stride = 32u; stride > 0u; stride = stride >> 1u) {
        if (lane < stride) { partial[lane] += partial[lane + stride]; }
        workgroupBarrier();
    }
}

fn tiles_x() -> u32 { return (WIDTH + TILE - 1u) / TILE; }

fn tile_count() -> u32 { return tiles_x() * ((HEIGHT + TILE - 1u) / TILE); }

@compute @workgroup_size(8, 8)
fn extra_from_heat(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    extra[i] = u32(floor(pow(clamp(finite_or_zero(source[i]), 0.0, 1.0), K) * 31.0));
}

@compute @workgroup_size(8, 8)
fn square_importance(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    let p = min(pow(sanitize(source[i]), K), 1.0e15);   // p² stays finite
    squared[i] = p * p;
}

// The Gaussian-weighted mean of squared over the taps within POOL_RADIUS of id inside the frame.
fn pooled_squared(id: vec3u) -> f32 {
    var total = 0.0;
    var norm = 0.0;
    let falloff = -0.5 / (POOL_SIGMA * POOL_SIGMA);
    for (var dy = -POOL_RADIUS; dy <= POOL_RADIUS; dy++) {
        let y = i32(id.y) + dy;
        if (y < 0 || y >= i32(HEIGHT)) { continue; }
        for (var dx = -POOL_RADIUS; dx <= POOL_RADIUS; dx++) {
            let x = i32(id.x) + dx;
            if (x < 0 || x >= i32(WIDTH)) { continue; }
            let g = exp(f32(dx * dx + dy * dy) * falloff);
            total += g * squared[u32(y) * WIDTH + u32(x)];
            norm += g;
        }
    }
    return total / norm;
}

@compute @workgroup_size(8, 8)
fn weigh(@builtin(global_invocation_id) id: vec3u, @builtin(local_invocation_index) lane: u32,
         @builtin(workgroup_id) tile: vec3u) {
    var w = 0.0;
    if (in_frame(id)) {
        var pooled = 0.0;
        if (POOL_RADIUS > 0) { pooled = pooled_squared(id); }
        w = min(sqrt(squared[pixel_index(id)] + pooled), 1.0e30);
        claim[pixel_index(id)] = w;
    }
    partial[lane] = w;
    sum_partial(lane);
    if (lane == 0u) { tile_sums[tile.y * tiles_x() + tile.x] = partial[0]; }
}

@compute @workgroup_size(64)
fn sum_weights(@builtin(local_invocation_index) lane: u32) {
    let tiles = tile_count();
    var total = 0.0;
    for (var t = lane; t < tiles; t += 64u) { total += tile_sums[t]; }
    partial[lane] = total;
    sum_partial(lane);
    if (lane == 0u) {
        budget.weight_sum = partial[0];
        atomicStore(&budget.assigned, 0u);
    }
}

@compute @workgroup_size(8, 8)
fn assign(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    let even = f32(TARGET) / f32(pixel_count());
    var ideal = even;
    if (budget.weight_sum > 0.0 && EVENLY_SPREAD < 1.0) {
        ideal = mix(claim[i] * (f32(TARGET) / budget.weight_sum), even, EVENLY_SPREAD);
    }
    let whole = floor(ideal);
    let count = u32(min(whole, f32(CAP)));
    extra[i] = count;
    claim[i] = select(ideal - whole, -1.0, count >= CAP);
    atomicAdd(&budget.assigned, count);
}

fn is_candidate(id: vec3u) -> bool {
    if (!in_frame(id)) { return false; }
    let i = pixel_index(id);
    return extra[i] < CAP && claim[i] >= THRESHOLD;
}

@compute @workgroup_size(8, 8)
fn count_candidates(@builtin(global_invocation_id) id: vec3u, @builtin(local_invocation_index) lane: u32,
                    @builtin(workgroup_id) tile: vec3u) {
    ranks[lane] = select(0u, 1u, is_candidate(id));
    workgroupBarrier();
    for (var stride = 32u; stride > 0u; stride = stride >> 1u) {
        if (lane < stride) { ranks[lane] += ranks[lane + stride]; }
        workgroupBarrier();
    }
    if (lane == 0u) { tile_offsets[tile.y * tiles_x() + tile.x] = ranks[0]; }
}

@compute @workgroup_size(64)
fn scan_candidates(@builtin(local_invocation_index) lane: u32) {
    let tiles = tile_count();
    var running = 0u;
    for (var base = 0u; base < tiles; base += 64u) {
        let t = base + lane;
        var count = 0u;
        if (t < tiles) { count = tile_offsets[t]; }
        ranks[lane] = count;
        workgroupBarrier();
        scan_ranks(lane);
        if (t < tiles) { tile_offsets[t] = running + ranks[lane] - count; }
        running += ranks[63];
        workgroupBarrier();
    }
    if (lane == 0u) {
        let assigned = atomicLoad(&budget.assigned);
        let quota = min(select(0u, TARGET - assigned, TARGET > assigned), running);
        budget.quota = quota;
        budget.candidates = running;
        atomicStore(&budget.assigned, assigned + quota);
        let next_round = assigned + quota < TARGET && (quota > 0u || THRESHOLD >= 0.0);
        let slot = 6u * NEXT_SLOT;
        spill_args[slot] = select(0u, tiles_x(), next_round);
        spill_args[slot + 1u] = select(0u, tile_count() / tiles_x(), next_round);
        spill_args[slot + 2u] = 1u;
        spill_args[slot + 3u] = select(0u, 1u, next_round);
        spill_args[slot + 4u] = 1u;
        spill_args[slot + 5u] = 1u;
    }
}

// (a · b) mod m for a, b < m < 2^31, by doubling (no 64-bit product needed).
fn mul_mod(a: u32, b: u32, m: u32) -> u32 {
    var result = 0u;
    for (var bit = 31i; bit >= 0i; bit--) {
        result = (result << 1u) % m;
        if (((b >> u32(bit)) & 1u) == 1u) { result = (result + a) % m; }
    }
    return result;
}

@compute @workgroup_size(8, 8)
fn take(@builtin(global_invocation_id) id: vec3u, @builtin(local_invocation_index) lane: u32,
        @builtin(workgroup_id) tile: vec3u) {
    let candidate = is_candidate(id);
    ranks[lane] = select(0u, 1u, candidate);
    workgroupBarrier();
    scan_ranks(lane);
    let quota = budget.quota;
    let total = budget.candidates;
    if (!candidate || quota == 0u) { return; }
    let rank = tile_offsets[tile.y * tiles_x() + tile.x] + ranks[lane] - 1u;
    if (quota == total || mul_mod(rank, quota, total) + quota >= total) {
        let i = pixel_index(id);
        extra[i] += 1u;
        claim[i] = -1.0;
    }
}

@compute @workgroup_size(8, 8)
fn half_buffer_error(@builtin(global_invocation_id) id: vec3u) {
    if (!in_frame(id)) { return; }
    let i = pixel_index(id);
    let n = pixel_count();
    var difference = 0.0;
    var intensity = 0.0;
    for (var c = 0u; c < 3u; c++) {
        let full = sanitize(source[c * n + i]);
        difference += abs(full - sanitize(half_radiance[c * n + i]));
        intensity += full;
    }
    error[i] = difference / (1e-4 + sqrt(intensity));
}
