// The entry conversion: the canvas of one pass of the network read from the planar NCHW f32 input
// image (the pipeline's format). Canvas row iy is image row IN_ROW0 + iy, and rows past ROWS repeat the
// last one, columns past IMAGE_W the last column (edge padding: an image network sees more of the image
// at its border, not a black frame); channels past CHANNELS in the last block are 0; NaN becomes 0 and
// ±Inf the largest finite value of the storage type. Used by pack.wgsl (which rounds to the storage
// type as it stores), and spliced by kernels.py into the network's first layer in place of
// load_blocks.wgsl, so that the layer reads the image itself (no pack dispatch). That layer takes the
// values unrounded: in fp16 its input keeps f32 precision, and no f16 round trip is paid per load (one
// per load cost ≈ 2% of the denoiser's CPU time on lavapipe, where each input pixel is loaded ≈ 4.5
// times by the 3×3 conv). The image may be seen flipped or turned (an ensemble's pass): pixel (r, c) of
// the IMAGE_H × IMAGE_W image as seen is ORIGIN + r · ROW_STRIDE + c · COL_STRIDE of each stored
// channel plane (kernels.dihedral_strides; IMAGE_W, 1, 0 as stored).
const CHANNELS: i32 = {{CHANNELS}};
const IMAGE_H: i32 = {{IMAGE_H}};
const IMAGE_W: i32 = {{IMAGE_W}};
const ROW_STRIDE: i32 = {{ROW_STRIDE}};
const COL_STRIDE: i32 = {{COL_STRIDE}};
const ORIGIN: i32 = {{ORIGIN}};
const IN_ROW0: i32 = {{IN_ROW0}};
const ROWS: i32 = {{ROWS}};

@group(0) @binding(0) var<storage, read> planar: array<f32>;

struct InputRow {
    start: i32,     // index of the row's first pixel in channel 4·cb of the image
    channels: i32,  // the block's channels that exist (4 but in the last block)
}

// Canvas row iy of channel block cb.
fn input_row(cb: i32, iy: i32) -> InputRow {
    return InputRow(4 * cb * IMAGE_H * IMAGE_W + ORIGIN + (IN_ROW0 + clamp(iy, 0, ROWS - 1)) * ROW_STRIDE,
                    CHANNELS - 4 * cb);
}

// Canvas pixel ix of `row`.
fn load_input(row: InputRow, ix: i32) -> vec4f {
    let pixel = row.start + clamp(ix, 0, IMAGE_W - 1) * COL_STRIDE;
    var value = vec4f(0.0);
    for (var k = 0; k < 4; k++) {
        if (k < row.channels) {
            value[k] = planar[pixel + k * IMAGE_H * IMAGE_W];
        }
    }
    return finite_or_zero(value);
}
