// load_blocks.wgsl for an input tensor too large for one storage binding (a concatenation at full
// resolution, e.g. the U-Net's top merge at 1080p against lavapipe's 128 MiB): kernels.py binds its
// blocks below IN_SPLIT as `src` and the rest as `src_upper`, two windows of one buffer, and swaps this
// module in. The branch depends on the block only, so every invocation of a workgroup takes the same
// side. The importing kernel defines IN_BLOCK (0 here: the windows start at the tensor), IN_H and IN_W.
// #import input_binding.wgsl
const IN_SPLIT: i32 = {{IN_SPLIT}};

@group(0) @binding({{UPPER_BINDING}}) var<storage, read> src_upper: array<vec4<T>>;

struct InputRow {
    start: i32,   // index of the row's first pixel in its binding
    upper: bool,  // in src_upper
}

// Row iy of input block cb (clamped to the tensor's rows: the caller zeroes what lies outside).
fn input_row(cb: i32, iy: i32) -> InputRow {
    let block = IN_BLOCK + cb;
    let upper = block >= IN_SPLIT;
    return InputRow((block - select(0, IN_SPLIT, upper)) * IN_H * IN_W + clamp(iy, 0, IN_H - 1) * IN_W, upper);
}

// Pixel ix of `row` (clamped to the tensor's columns).
fn load_input(row: InputRow, ix: i32) -> vec4f {
    let pixel = row.start + clamp(ix, 0, IN_W - 1);
    if (row.upper) {
        return vec4f(src_upper[pixel]);
    }
    return vec4f(src[pixel]);
}
