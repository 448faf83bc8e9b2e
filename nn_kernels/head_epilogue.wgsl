// A 1×1 convolution (the network's head, without activation) run in a 3×3 convolution's epilogue
// (kernels.Conv3x3Kernel with a head): the tile's TILE_C output blocks are all of the layer's channels,
// so the tile's 4 pixels of activations go through the head's HEAD_BLOCKS × TILE_C weight blocks
// (mat4x4: column j holds the head's 4 output channels' weights for input channel j, as in
// PackedWeights) as 4-pixel matrices, like the tile's own accumulation (kernels.tile_blocks_code writes
// the sum out), and the head's output, not the layer's, is stored.
const HEAD_BLOCKS: i32 = {{HEAD_BLOCKS}};

struct HeadWeights {
    blocks: array<mat4x4f, HEAD_BLOCKS * TILE_C>,  // block (k, t) at k * TILE_C + t
    bias: array<vec4f, HEAD_BLOCKS>,
}

@group(0) @binding({{HEAD_BINDING}}) var<uniform> head: HeadWeights;

// The head's input: the layer's activations of 4 pixels (columns), rounded to the storage type,
// exactly as if stored and read back by a dispatch of the head's own.
fn head_input(pixels: mat4x4f) -> mat4x4f {
    return mat4x4f(vec4f(to_storage(activate(pixels[0]))), vec4f(to_storage(activate(pixels[1]))),
                   vec4f(to_storage(activate(pixels[2]))), vec4f(to_storage(activate(pixels[3]))));
}

fn head_bias(block: i32) -> mat4x4f {
    return mat4x4f(head.bias[block], head.bias[block], head.bias[block], head.bias[block]);
}

// Stores the head's output block `block` of the 4 pixels ox0.. of row oy.
fn store_head_pixels(block: i32, oy: i32, ox0: i32, pixels: mat4x4f) {
    for (var p = 0; p < 4; p++) {
        if (ox0 + p < OUT_W) {
            store_output(block, oy * OUT_W + ox0 + p, pixels[p]);
        }
    }
}
