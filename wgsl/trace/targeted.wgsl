// The targeted tracer pass: each pixel takes its own number of samples (sample_counts), traced over the
// compacted work list of trace/work_list_build.wgsl, so the pass costs what its samples cost: pixels
// without samples take no invocation, and neighbouring invocations take nearly the same number. The
// host records the list's batches one after another (params.chunk_start: the batch's first item;
// params.chunk_size: the most samples per item), each a trace_items dispatch then a resolve_items one.
//   trace_items:   one invocation per item: its samples, numbered after the samples its pixel held
//                  before the pass and by their place in the pixel's split (the indices, so the paths,
//                  that a uniform pass would give the pixel). A pixel's only item folds its sums into
//                  the pixel's running means at once; an item of several leaves them in its slot.
//   resolve_items: the first invocation of each entry of several items in the batch adds up the slots
//                  of the entry's items there, in order, and folds the sums into the pixel's means
//                  (dispatched over the batch's items of such entries only: the list puts them first).
// Where LOOP_BUDGET (trace/trace.wgsl) cuts an item short, its pixel records only the samples completed,
// as in a uniform pass; the pixel's later items keep their numbers, so a later pass, numbered after the
// pixel's spp, may repeat a few of their indices (lavapipe only, on very long paths).

// #import trace/trace.wgsl
// #import trace/work_list.wgsl

@group(3) @binding(0) var<storage, read> entries: array<Entry>;
@group(3) @binding(1) var<storage, read> totals: Totals;
@group(3) @binding(2) var<storage, read_write> slots: array<SampleSums>;   // per item of the batch
@group(3) @binding(3) var<storage, read_write> slot_entries: array<u32>;   // each slot's entry, or FOLDED

const FOLDED: u32 = 0xffffffffu;   // the slot's item was its pixel's only one, already folded

// Items in the current batch.
fn batch_items() -> u32 {
    let first = params.chunk_start;
    return min(select(0u, totals.items - first, totals.items > first), totals.batch_items);
}

// The entry that holds work item `item`: past the items of pixels of several items, each entry holds one
// item, so it is found by subtraction; before them, by a binary search for the last entry whose first
// item is at most `item` (log2 of the entries in dependent loads: 21 at 1080p).
fn entry_of(item: u32) -> u32 {
    if item >= totals.waiting_items {
        return item - totals.waiting_items + totals.waiting_entries;
    }
    var low = 0u;
    var high = totals.waiting_entries;
    while high - low > 1u {
        let middle = (low + high) / 2u;
        if entries[middle].first_item <= item {
            low = middle;
        } else {
            high = middle;
        }
    }
    return low;
}

// The block of 64 items workgroup `w` of `n` takes: the list's blocks from both ends in turn (0, n − 1,
// 1, n − 2, …). The list runs from its largest items to its smallest, and a CPU driver hands each of its
// threads one contiguous range of workgroups: in list order the first thread would get all the large
// items and the others would wait for it (a targeted pass of 1 and 13 samples in even shares took 1.77×
// a uniform pass on lavapipe, in the same CPU time); alternating the ends gives every range a share of
// both. A GPU schedules workgroups as they free up, where the order matters little.
fn interleaved_block(w: u32, n: u32) -> u32 {
    return select(n - 1u - w / 2u, w / 2u, (w & 1u) == 0u);
}

@compute @workgroup_size(64)
fn trace_items(@builtin(workgroup_id) group: vec3u, @builtin(num_workgroups) groups: vec3u,
               @builtin(local_invocation_index) lane: u32) {
    begin_traversal(lane);
    let slot = interleaved_block(group.x, groups.x) * 64u + lane;
    let has_item = slot < batch_items();
    var entry = 0u;
    var owner = Entry(0u, 0u, 0u);
    var range = vec2u(0u);
    if has_item {
        let item = params.chunk_start + slot;
        entry = entry_of(item);
        owner = entries[entry];
        range = item_range(sample_counts[owner.pixel], params.chunk_size, item - owner.first_item);
    }
    let pixel = owner.pixel;
    let sums = trace_samples(pixel, vec2u(pixel % params.width, pixel / params.width),
                             params.sample_offset + owner.held + range.x, range.y);
    if has_item {
        if range.y == sample_counts[pixel] {
            if sums.count > 0u {
                fold_samples(pixel, owner.held, sums);
            }
            slot_entries[slot] = FOLDED;
        } else {
            slots[slot] = sums;
            slot_entries[slot] = entry;
        }
    }
}

@compute @workgroup_size(64)
fn resolve_items(@builtin(workgroup_id) group: vec3u, @builtin(local_invocation_index) lane: u32) {
    let slot = group.x * 64u + lane;
    let count = batch_items();
    if slot >= count {
        return;
    }
    let entry = slot_entries[slot];
    if entry == FOLDED || (slot > 0u && slot_entries[slot - 1u] == entry) {
        return;
    }
    var sums = slots[slot];
    for (var next = slot + 1u; next < count && slot_entries[next] == entry; next += 1u) {
        sums = add_sums(sums, slots[next]);
    }
    if sums.count > 0u {
        let pixel = entries[entry].pixel;
        fold_samples(pixel, out_spp[pixel], sums);
    }
}
