// A 2×2 stride-2 max pool of a convolution's output, computed in the convolution's epilogue
// (graph.NetworkGraph.epilogue_pools): after every invocation of the workgroup has stored its pixels,
// the workgroup reads its own output tile back (it is still in cache) and writes the tile's pooled
// pixels to `pooled`, so the pooled tensor costs no dispatch of its own and the full-resolution output
// is not read again from memory. Floor mode, max taken in the storage type (exactly maxpool.wgsl).
// The importing kernel defines OUT_H, OUT_W, TILE_C and `dst`; its workgroup tiles start at even rows and
// columns, so each pooled pixel's 2×2 window lies inside one workgroup's tile.
const POOL_H: i32 = OUT_H / 2;
const POOL_W: i32 = OUT_W / 2;
// The pooled tensor's first block minus the output's: pooled block = output block + POOL_BLOCK_SHIFT.
const POOL_BLOCK_SHIFT: i32 = {{POOL_BLOCK_SHIFT}};

@group(0) @binding({{POOL_BINDING}}) var<storage, read_write> pooled: array<vec4<T>>;

// Pools the tile of TILE_W × TILE_H output pixels × TILE_C blocks whose top-left pixel is (x0, y0), the
// group's blocks from header.out_block on. Every invocation of the workgroup calls it once, from uniform
// control flow, after its own stores.
fn pool_tile(x0: i32, y0: i32, invocation: i32) {
    storageBarrier();  // the whole tile is stored and visible to the workgroup
    const TILE_PIXELS: i32 = (TILE_W / 2) * (TILE_H / 2);  // pooled pixels of one block of the tile
    for (var index = invocation; index < TILE_PIXELS * TILE_C; index += 64) {
        let block = header.out_block + index / TILE_PIXELS;
        let py = y0 / 2 + (index % TILE_PIXELS) / (TILE_W / 2);
        let px = x0 / 2 + index % (TILE_W / 2);
        if (py < POOL_H && px < POOL_W) {
            let top = block * OUT_H * OUT_W + 2 * py * OUT_W + 2 * px;
            let bottom = top + OUT_W;
            pooled[(block + POOL_BLOCK_SHIFT) * POOL_H * POOL_W + py * POOL_W + px] =
                max(max(dst[top], dst[top + 1]), max(dst[bottom], dst[bottom + 1]));
        }
    }
}
