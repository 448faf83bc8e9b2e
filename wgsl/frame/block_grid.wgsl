// The grid of BLOCK×BLOCK-pixel blocks over a WIDTH×HEIGHT frame (fewer pixels in the last row and column
// of blocks when the size is not a multiple), and reading a per-block plane back at a pixel: bilinear
// between block centres, clamped at the edges (wgpu_rt.frame.lowband.bilinear_up is the reference).
// #import frame/common.wgsl

const BLOCK: u32 = 4u;

fn block_count() -> vec2u { return vec2u((WIDTH + BLOCK - 1u) / BLOCK, (HEIGHT + BLOCK - 1u) / BLOCK); }

// The pixels of block `block`: first (inclusive) and last (exclusive) corners.
fn block_first(block: vec2u) -> vec2u { return BLOCK * block; }
fn block_last(block: vec2u) -> vec2u { return min(BLOCK * block + BLOCK, vec2u(WIDTH, HEIGHT)); }

// Where pixel `pixel` reads a block plane: the four blocks' indices within a plane and the weights.
struct BlockLookup { i00: u32, i01: u32, i10: u32, i11: u32, t: vec2f }

fn block_axis(position: u32, count: u32) -> vec3f {
    let u = clamp((f32(position) + 0.5) / f32(BLOCK) - 0.5, 0.0, f32(count - 1u));
    let first = floor(u);
    return vec3f(first, min(first + 1.0, f32(count - 1u)), u - first);
}

fn block_lookup(pixel: vec2u) -> BlockLookup {
    let blocks = block_count();
    let ax = block_axis(pixel.x, blocks.x);
    let ay = block_axis(pixel.y, blocks.y);
    let row0 = u32(ay.x) * blocks.x;
    let row1 = u32(ay.y) * blocks.x;
    return BlockLookup(row0 + u32(ax.x), row0 + u32(ax.y), row1 + u32(ax.x), row1 + u32(ax.y), vec2f(ax.z, ay.z));
}

// The bilinear value from the four blocks' values (v00, v01 on the first row of blocks).
fn block_mix(at: BlockLookup, v00: f32, v01: f32, v10: f32, v11: f32) -> f32 {
    return mix(mix(v00, v01, at.t.x), mix(v10, v11, at.t.x), at.t.y);
}
