// 3×3 stride-1 convolution with the input staged in workgroup memory; the same 4-pixel × 16-channel
// register tile per invocation as conv3x3.wgsl (conv3x3_tile.wgsl). A workgroup computes an 8-row ×
// 32-pixel output tile. Per input channel block it first loads the tile's 10 × 34 input pixels (tile +
// 1-pixel halo, zero padding applied here) cooperatively into `staged`, consecutive invocations
// loading consecutive pixels, then each invocation reads its 3 × 6 input pixels from workgroup memory:
// every input pixel is read from device memory ≈ 1.3 times instead of 4.5 times (the overlap of the
// invocations' 6-pixel rows and 3-row windows), and the inner loop needs no bounds checks. Worth it
// where workgroup memory is on-chip (discrete GPUs); on lavapipe it is ordinary memory read per lane,
// so the staging and barriers only add work (see kernels.Conv3x3Kernel). With weights_workgroup.wgsl
// (conv tiling "staged-weights") each input block's weight blocks are staged beside its pixels
// (a stage call per window, spliced in by kernels.Conv3x3Kernel; none with the other weight fetches).
{{ENABLE_F16}}
// #import conv3x3_tile.wgsl

const HALO_W: i32 = TILE_W + 2;
const HALO_PIXELS: i32 = HALO_W * (TILE_H + 2);
const STAGING_STEPS: i32 = (HALO_PIXELS + 63) / 64;

var<workgroup> staged: array<vec4f, HALO_PIXELS>;

// Loads input block cb of the halo tile whose top-left input pixel is (x0, y0) into `staged`.
fn stage_block(cb: i32, x0: i32, y0: i32, invocation: i32) {
    for (var step = 0; step < STAGING_STEPS; step++) {
        let index = step * 64 + invocation;
        if (index < HALO_PIXELS) {
            let iy = y0 + index / HALO_W;
            let ix = x0 + index % HALO_W;
            let value = load_input(input_row(cb, iy), ix);
            staged[index] = select(vec4f(0.0), value, iy >= 0 && iy < IN_H && ix >= 0 && ix < IN_W);
        }
    }
}

// No early exit (the barriers and weight_block need every invocation): invocations past the output's
// edge compute on the zero-padded halo and store nothing.
@compute @workgroup_size(64, 1, 1)
fn main(@builtin(workgroup_id) wid: vec3u, @builtin(local_invocation_id) local_id: vec3u, lane: WeightLane) {
    enter_group(wid.z);
    let invocation = i32(local_id.x);
    let tile_x = (invocation % 8) * 4;
    let tile_y = invocation / 8;
    let halo_x0 = i32(wid.x) * TILE_W - PAD_LEFT;
    let halo_y0 = i32(wid.y) * TILE_H - PAD_TOP;
    var tile = bias_tile();
    for (var cb = 0; cb < IN_BLOCKS; cb++) {
        workgroupBarrier();  // every invocation is done reading the previous block
        stage_block(cb, halo_x0, halo_y0, invocation);
{{STAGE_WEIGHTS}}
        workgroupBarrier();
        for (var ky = 0; ky < 3; ky++) {
            let row = (tile_y + ky) * HALO_W + tile_x;
            accumulate_row(&tile, cb, ky, lane, staged[row], staged[row + 1], staged[row + 2],
                           staged[row + 3], staged[row + 4], staged[row + 5]);
        }
    }
    let oy = i32(wid.y) * TILE_H + tile_y;
    if (oy < OUT_H) {
        store_tile(tile, oy, i32(wid.x) * TILE_W + tile_x);
    }
    pool_tile(i32(wid.x) * TILE_W, i32(wid.y) * TILE_H, invocation);
}
