// Bindings of every weighted layer kernel (conv, conv3x3, conv_transpose, gemm) but the input (binding
// 0: input_binding.wgsl, or in the convolutions load_blocks.wgsl / load_planar.wgsl): the output
// (store_blocks.wgsl, or store_planar.wgsl in the network's last layer; the importing kernel stores
// through store_output), the weight fetch that kernels.py splices in for the
// adapter (uniform windows, subgroup broadcast or storage), and a header per output-block group
// holding the bias of the group's TILE_C output blocks and the index of its first block. The
// importing kernel defines TILE_C and calls enter_group(workgroup_id.z) first.
//
// A layer runs as one dispatch whose workgroup_id.z is the group (GROUPS headers, and the groups'
// weight windows GROUP_MATS blocks apart in one binding, fetched from weight_window on), so a
// low-resolution layer still has G× the workgroups of one group; or, where its weights do not fit one
// binding, or uniform windows are preferred (kernels.PackedWeights), as one dispatch per group with
// that group's header (GROUPS = 1) and windows bound.

struct GroupHeader {
    bias: array<vec4f, TILE_C>,
    out_block: i32,
}

const GROUPS: u32 = {{GROUPS}}u;
const GROUP_MATS: i32 = {{GROUP_MATS}};

// #import store_blocks.wgsl

{{WEIGHT_FETCH}}
@group(0) @binding(3) var<uniform> headers: array<GroupHeader, GROUPS>;

var<private> header: GroupHeader;
var<private> weight_window: i32;

fn enter_group(group: u32) {
    header = headers[group];
    weight_window = i32(group) * GROUP_MATS;
}
