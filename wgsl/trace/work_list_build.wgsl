// Builds the work list of a targeted tracer pass (trace/work_list.wgsl) from the per-pixel sample counts.
// Entries are ordered by group (list_group: pixels of several items first, then by size class, the
// size of their largest item, largest first), then by place in the film's 8 × 8 tiles (tiles in raster
// order, pixels in raster order inside each): neighbouring items hold nearly the same number of samples,
// so the invocations of a subgroup finish together, neighbours in the list are mostly neighbours on the
// film in both directions, as in a uniform pass's 8 × 8 workgroups (coherent rays and node fetches),
// pixels without samples take no invocation, and the items whose sums wait for resolve_items come
// first, so that pass covers only them. Only integer prefix sums decide where anything goes: the same
// counts give the same list.
//
// A block is one 8 × 8 tile (lane l: its pixel (l mod 8, l / 8), none past the film's edge); its counts
// per group sit group-major in `counts` (group · blocks + block) as (items, entries) pairs, and a list
// position is the sum of the pairs before it in that order.
//   count_items:   per block: the (items, entries) of each group present → counts (cleared before, so
//                  absent groups count 0), and of each pixel, those of its group before it in the
//                  block → local_offsets.
//   scan_runs:     one invocation per run of 64 consecutive cells of counts: their exclusive prefix sums
//                  in place, the run's totals → run_sums (items at [run], entries runs() further on).
//   scan_run_sums: one workgroup: exclusive prefix sums of run_sums in place (items and entries apart),
//                  the totals → totals, and the workgroups of each of the BATCHES batches' trace_items
//                  (all its items) and resolve_items (its items of pixels of several items) → batch_args.
//   place_entries: per pixel with samples: its entry (pixel, first item, samples held) where the sums say.

// #import trace/work_list.wgsl
// #import trace/workgroup_scan.wgsl

override WIDTH: u32;
override HEIGHT: u32;
override ITEM_SAMPLES: u32;   // at most 64 (the masks hold 128 groups)
override BATCH_ITEMS: u32;    // a multiple of 64
override BATCHES: u32;

@group(0) @binding(0) var<storage, read> sample_counts: array<u32>;
@group(0) @binding(1) var<storage, read> spp: array<u32>;
@group(0) @binding(2) var<storage, read_write> counts: array<vec2u>;
@group(0) @binding(3) var<storage, read_write> local_offsets: array<vec2u>;
@group(0) @binding(4) var<storage, read_write> run_sums: array<u32>;
@group(0) @binding(5) var<storage, read_write> entries: array<Entry>;
@group(0) @binding(6) var<storage, read_write> totals: Totals;
// per batch: (x, y, z) workgroups of trace_items, then of resolve_items
@group(0) @binding(7) var<storage, read_write> batch_args: array<u32>;

var<workgroup> lane_items: array<u32, 64>;

fn pixel_count() -> u32 { return WIDTH * HEIGHT; }

const BLOCK_SIDE: u32 = 8u;   // a block is BLOCK_SIDE² = 64 pixels, == wgpu_rt.trace.trace_pass.TILE

fn tile_columns() -> u32 { return (WIDTH + BLOCK_SIDE - 1u) / BLOCK_SIDE; }

fn pixel_blocks() -> u32 { return tile_columns() * ((HEIGHT + BLOCK_SIDE - 1u) / BLOCK_SIDE); }

// Lane `lane`'s pixel of block (tile) `block`, or pixel_count() past the film's edge.
fn block_pixel(block: u32, lane: u32) -> u32 {
    let x = (block % tile_columns()) * BLOCK_SIDE + lane % BLOCK_SIDE;
    let y = (block / tile_columns()) * BLOCK_SIDE + lane / BLOCK_SIDE;
    return select(pixel_count(), y * WIDTH + x, x < WIDTH && y < HEIGHT);
}

// (group, block) cells of `counts`
fn count_cells() -> u32 { return 2u * ITEM_SAMPLES * pixel_blocks(); }

fn runs() -> u32 { return (count_cells() + 63u) / 64u; }

// Workgroups run over a 2-D grid (a dimension holds at most 65535 of them): the index of this one.
fn group_index(workgroup: vec3u, workgroups: vec3u) -> u32 { return workgroup.y * workgroups.x + workgroup.x; }

// The lanes of a group, and of those the lanes with more than one item, as 64-bit masks (two words
// each, lane l at bit l mod 32 of word l / 32): a lane's entries before it in its group are the bits
// below its own, so no lane loops over the block (slow on a CPU driver); only its items need a turn per
// earlier lane of several items (none in the groups of single items).
var<workgroup> group_lanes: array<atomic<u32>, 256>;
var<workgroup> multi_lanes: array<atomic<u32>, 256>;

// Items beyond one per lane over the lanes of `multi` (a mask word of lanes base..base + 31).
fn extra_items(multi: u32, base: u32) -> u32 {
    var extra = 0u;
    var bits = multi;
    while bits != 0u {
        extra += lane_items[base + firstTrailingBit(bits)] - 1u;
        bits &= bits - 1u;
    }
    return extra;
}

@compute @workgroup_size(64)
fn count_items(@builtin(workgroup_id) workgroup: vec3u, @builtin(num_workgroups) workgroups: vec3u,
               @builtin(local_invocation_index) lane: u32) {
    let block = group_index(workgroup, workgroups);
    if block >= pixel_blocks() { return; }
    let pixel = block_pixel(block, lane);
    var count = 0u;
    if pixel < pixel_count() { count = sample_counts[pixel]; }
    let items = items_of(count, ITEM_SAMPLES);
    lane_items[lane] = items;
    // a CPU driver may hand a workgroup the memory of the one it ran before: clear the masks first
    for (var word = lane; word < 256u; word += 64u) {
        atomicStore(&group_lanes[word], 0u);
        atomicStore(&multi_lanes[word], 0u);
    }
    workgroupBarrier();
    let group = list_group(count, ITEM_SAMPLES);
    let bit = 1u << (lane % 32u);
    if count > 0u {
        atomicOr(&group_lanes[2u * group + lane / 32u], bit);
        if items > 1u { atomicOr(&multi_lanes[2u * group + lane / 32u], bit); }
    }
    workgroupBarrier();
    if count == 0u { return; }
    let members = vec2u(atomicLoad(&group_lanes[2u * group]), atomicLoad(&group_lanes[2u * group + 1u]));
    let multi = vec2u(atomicLoad(&multi_lanes[2u * group]), atomicLoad(&multi_lanes[2u * group + 1u]));
    // lanes below this one, per word
    let below = select(vec2u(bit - 1u, 0u), vec2u(0xffffffffu, bit - 1u), lane >= 32u);
    let entries_before = countOneBits(members.x & below.x) + countOneBits(members.y & below.y);
    let items_before = entries_before + extra_items(multi.x & below.x, 0u) + extra_items(multi.y & below.y, 32u);
    local_offsets[pixel] = vec2u(items_before, entries_before);
    let entries_total = countOneBits(members.x) + countOneBits(members.y);
    if entries_before + 1u == entries_total {   // the group's last pixel in the block writes its totals
        let items_total = entries_total + extra_items(multi.x, 0u) + extra_items(multi.y, 32u);
        counts[group * pixel_blocks() + block] = vec2u(items_total, entries_total);
    }
}

@compute @workgroup_size(64)
fn scan_runs(@builtin(global_invocation_id) id: vec3u) {
    let run = id.x;
    if run >= runs() { return; }
    var running = vec2u(0u);
    for (var at = 64u * run; at < min(64u * run + 64u, count_cells()); at += 1u) {
        let value = counts[at];
        counts[at] = running;
        running += value;
    }
    run_sums[run] = running.x;
    run_sums[runs() + run] = running.y;
}

@compute @workgroup_size(64)
fn scan_run_sums(@builtin(local_invocation_index) lane: u32) {
    var grand = vec2u(0u);
    for (var part = 0u; part < 2u; part += 1u) {
        var running = 0u;
        for (var base = 0u; base < runs(); base += 64u) {
            let at = part * runs() + base + lane;
            var value = 0u;
            if base + lane < runs() { value = run_sums[at]; }
            ranks[lane] = value;
            workgroupBarrier();
            scan_ranks(lane);
            if base + lane < runs() { run_sums[at] = running + ranks[lane] - value; }
            running += ranks[63];
            workgroupBarrier();
        }
        grand[part] = running;
    }
    // where the groups of single items start: items before them wait for resolve_items
    storageBarrier();
    let singles = ITEM_SAMPLES * pixel_blocks();
    let waiting = run_sums[singles / 64u] + counts[singles].x;
    let waiting_entries = run_sums[runs() + singles / 64u] + counts[singles].y;
    if lane == 0u { totals = Totals(grand.x, grand.y, BATCH_ITEMS, waiting, waiting_entries); }
    for (var batch = lane; batch < BATCHES; batch += 64u) {
        let first = batch * BATCH_ITEMS;
        let items = min(select(0u, grand.x - first, grand.x > first), BATCH_ITEMS);
        let resolved = min(select(0u, waiting - first, waiting > first), BATCH_ITEMS);
        batch_args[6u * batch] = (items + 63u) / 64u;
        batch_args[6u * batch + 1u] = 1u;
        batch_args[6u * batch + 2u] = 1u;
        batch_args[6u * batch + 3u] = (resolved + 63u) / 64u;
        batch_args[6u * batch + 4u] = 1u;
        batch_args[6u * batch + 5u] = 1u;
    }
}

@compute @workgroup_size(64)
fn place_entries(@builtin(workgroup_id) workgroup: vec3u, @builtin(num_workgroups) workgroups: vec3u,
                 @builtin(local_invocation_index) lane: u32) {
    let block = group_index(workgroup, workgroups);
    if block >= pixel_blocks() { return; }
    let pixel = block_pixel(block, lane);
    if pixel >= pixel_count() { return; }
    let count = sample_counts[pixel];
    if count == 0u { return; }
    let cell = list_group(count, ITEM_SAMPLES) * pixel_blocks() + block;
    let before = counts[cell] + local_offsets[pixel];
    let first_item = run_sums[cell / 64u] + before.x;
    let entry = run_sums[runs() + cell / 64u] + before.y;
    entries[entry] = Entry(pixel, first_item, spp[pixel]);
}
