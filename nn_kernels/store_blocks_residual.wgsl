// store_blocks.wgsl with an Add folded in (graph.NetworkGraph.epilogue_adds): the layer stores its
// output plus the same pixel and channels of `residual`, a tensor of the output's shape, RESIDUAL_SHIFT
// blocks after the output's block in its own binding. Swapped in by kernels.py. The importing kernel
// defines OUT_PLANE (output pixels per block).
@group(0) @binding(1) var<storage, read_write> dst: array<vec4<T>>;
@group(0) @binding({{RESIDUAL_BINDING}}) var<storage, read> residual: array<vec4<T>>;

const RESIDUAL_SHIFT: i32 = {{RESIDUAL_SHIFT}};

// Stores `value` + the residual (sanitized) as pixel `pixel` (y · OUT_W + x) of block `block` of the output.
fn store_output(block: i32, pixel: i32, value: vec4f) {
    let added = vec4f(residual[(block + RESIDUAL_SHIFT) * OUT_PLANE + pixel]);
    dst[block * OUT_PLANE + pixel] = to_storage(value + added);
}
