// Where a convolution's input pixels come from: an NC4HW4 activation tensor. load_planar.wgsl, swapped
// in by kernels.py for the network's first layer, reads the planar input image instead (no pack
// dispatch). The importing kernel defines IN_BLOCK, IN_H and IN_W.
// #import input_binding.wgsl

struct InputRow {
    start: i32,  // index of the row's first pixel in src
}

// Row iy of input block cb (clamped to the tensor's rows: the caller zeroes what lies outside).
fn input_row(cb: i32, iy: i32) -> InputRow {
    return InputRow((IN_BLOCK + cb) * IN_H * IN_W + clamp(iy, 0, IN_H - 1) * IN_W);
}

// Pixel ix of `row` (clamped to the tensor's columns).
fn load_input(row: InputRow, ix: i32) -> vec4f {
    return vec4f(src[row.start + clamp(ix, 0, IN_W - 1)]);
}
