// A prefix sum over the 64 invocations of a workgroup, shared by the kernels that rank or place items
// (frame/adaptive.wgsl, trace/work_list_build.wgsl): each lane writes its value into ranks[lane], every lane
// of the workgroup calls scan_ranks, and ranks[lane] then holds the sum of ranks[0..=lane].

var<workgroup> ranks: array<u32, 64>;

// Inclusive prefix sum of ranks[0..64) in place (Hillis–Steele); every lane of the workgroup calls it.
fn scan_ranks(lane: u32) {
    for (var offset = 1u; offset < 64u; offset = offset << 1u) {
        var sum = ranks[lane];
        if (lane >= offset) { sum += ranks[lane - offset]; }
        workgroupBarrier();
        ranks[lane] = sum;
        workgroupBarrier();
    }
}
