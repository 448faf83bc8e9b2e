// Writes each invocation's subgroup size in one 1-D workgroup of 64. WebGPU adapters do not report
// their subgroup width (the spec promises only 4), so kernels that specialize on it (the BVH packet
// traversal, the NN weight fetch) read what this probe saw: GpuContext.subgroup_sizes.
@group(0) @binding(0) var<storage, read_write> sizes: array<u32, 64>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(local_invocation_index) index: u32, @builtin(subgroup_size) size: u32) {
    sizes[index] = size;
}
