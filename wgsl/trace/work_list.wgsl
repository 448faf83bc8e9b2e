// The work list of a targeted tracer pass, shared by its builder (trace/work_list_build.wgsl) and its
// kernels (trace/targeted.wgsl). Each pixel with samples to take is one entry; its `count` samples are
// split into ceil(count / item_samples) work items of near-equal size (the first count mod items of them
// take one sample more), so no item holds more than item_samples samples, the tracer's chunk size.

struct Entry {
    pixel: u32,
    first_item: u32,   // where its items start in the list (they are consecutive)
    held: u32,         // samples the pixel held before the pass: its new ones are numbered after them
}

struct Totals {
    items: u32,
    entries: u32,
    batch_items: u32,     // items per batch (the last one may hold fewer)
    waiting_items: u32,   // the items of pixels of several items, which come first (their sums wait for
    waiting_entries: u32, // resolve_items), and those pixels' entries: after them, one item per entry
}

fn items_of(count: u32, item_samples: u32) -> u32 {
    return (count + item_samples - 1u) / item_samples;
}

// The size of a pixel's largest item, 1..item_samples; 0 for a pixel without samples.
fn size_class(count: u32, item_samples: u32) -> u32 {
    let items = max(items_of(count, item_samples), 1u);
    return (count + items - 1u) / items;
}

// Where a pixel with samples sits in the list's order, 0..2·item_samples − 1: pixels of several items
// first (their items' sums wait for resolve_items; the others fold at once), each group by size class
// from the largest down.
fn list_group(count: u32, item_samples: u32) -> u32 {
    let single = items_of(count, item_samples) == 1u;
    return select(0u, item_samples, single) + item_samples - size_class(count, item_samples);
}

// Item `item` of a pixel's `count` samples: (its first sample, counted from the pass's start; its size).
fn item_range(count: u32, item_samples: u32, item: u32) -> vec2u {
    let items = items_of(count, item_samples);
    let size = count / items;
    let larger = count % items;
    return vec2u(item * size + min(item, larger), size + select(0u, 1u, item < larger));
}
