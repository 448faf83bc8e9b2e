// Writes each invocation's subgroup size, so the engine can specialize kernels to the adapter's
// subgroup width (WebGPU only promises 4 lanes; adapters do not report their actual width).
@group(0) @binding(0) var<storage, read_write> sizes: array<u32, 64>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(local_invocation_index) index: u32, @builtin(subgroup_size) size: u32) {
    sizes[index] = size;
}
