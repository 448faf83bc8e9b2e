// Bindings of every weighted layer kernel (conv, conv3x3, conv_transpose, gemm): input and output
// activations as vec4 channel blocks of T, the weight fetch that kernels.py splices in for the
// adapter (uniform windows, subgroup broadcast or storage), and a per-dispatch header holding the
// bias of the group's TILE_C output blocks and the index of its first block. The importing kernel
// defines TILE_C.

struct GroupHeader {
    bias: array<vec4f, TILE_C>,
    out_block: i32,
}

@group(0) @binding(0) var<storage, read> src: array<vec4<T>>;
@group(0) @binding(1) var<storage, read_write> dst: array<vec4<T>>;
{{WEIGHT_FETCH}}
@group(0) @binding(3) var<uniform> header: GroupHeader;
