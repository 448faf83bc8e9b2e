// Where a weighted layer's output goes: an NC4HW4 activation tensor (the engine's internal layout).
// store_planar.wgsl, swapped in by kernels.py for the network's last layer, writes the planar f32 image
// instead. The importing kernel defines OUT_PLANE (output pixels per block).
@group(0) @binding(1) var<storage, read_write> dst: array<vec4<T>>;

// Stores `value` (sanitized) as pixel `pixel` (y · OUT_W + x) of block `block` of the output buffer.
fn store_output(block: i32, pixel: i32, value: vec4f) {
    dst[block * OUT_PLANE + pixel] = to_storage(value);
}
