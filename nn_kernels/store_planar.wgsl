// The exit conversion: NC4HW4 values → planar NCHW f32 (the pipeline's format), cropping the canvas back
// to the image and dropping the padding channels of the last block: canvas rows ROW_FROM ..
// ROW_FROM + ROWS - 1 (the first IMAGE_W columns) go to image rows OUT_ROW0.. of an IMAGE_H-row image.
// Used by unpack.wgsl, and spliced by kernels.py into the network's last layer in place of
// store_blocks.wgsl, so that the layer writes the image itself (no unpack dispatch). Values are
// sanitized and rounded to the storage type first, exactly as a stored activation read back by unpack.
// The image may be seen flipped or turned, as load_planar.wgsl describes (an ensemble's pass writes its
// output back as stored); values are scaled by WEIGHT and, with ACCUMULATE, added to the image's.
// The importing kernel defines OUT_W (canvas columns).
const CHANNELS: i32 = {{CHANNELS}};
const IMAGE_H: i32 = {{IMAGE_H}};
const IMAGE_W: i32 = {{IMAGE_W}};
const ROW_STRIDE: i32 = {{ROW_STRIDE}};
const COL_STRIDE: i32 = {{COL_STRIDE}};
const ORIGIN: i32 = {{ORIGIN}};
const OUT_ROW0: i32 = {{OUT_ROW0}};
const ROW_FROM: i32 = {{ROW_FROM}};
const ROWS: i32 = {{ROWS}};
const WEIGHT: f32 = {{WEIGHT}};
const ACCUMULATE: bool = {{ACCUMULATE}};

@group(0) @binding(1) var<storage, read_write> planar: array<f32>;

// Stores `value` as canvas pixel `pixel` (y · OUT_W + x) of channel block `block` (counted from the
// tensor's first block), if the pixel and channels lie inside the image.
fn store_output(block: i32, pixel: i32, value: vec4f) {
    let row = pixel / OUT_W - ROW_FROM;
    let x = pixel % OUT_W;
    if (row < 0 || row >= ROWS || x >= IMAGE_W) {
        return;
    }
    let stored = vec4f(to_storage(value)) * WEIGHT;
    let at = ORIGIN + (OUT_ROW0 + row) * ROW_STRIDE + x * COL_STRIDE;
    for (var k = 0; k < 4; k++) {
        let channel = 4 * block + k;
        if (channel < CHANNELS) {
            let index = channel * IMAGE_H * IMAGE_W + at;
            if (ACCUMULATE) {
                planar[index] += stored[k];
            } else {
                planar[index] = stored[k];
            }
        }
    }
}
