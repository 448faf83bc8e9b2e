// A binding of weight blocks (mat4x4: 4 input × 4 output channels) for the fetch functions of
// weights_subgroup.wgsl / weights_uniform.wgsl / weights_workgroup.wgsl: a uniform block when it fits,
// else read-only storage. A slot is 64 bytes: a mat4x4f, or for half-precision multiply-adds
// (weights_uniform_f16.wgsl, storage only) array<mat4x4<f16>, 2> whose first matrix is the block.
@group(0) @binding({{WEIGHT_BINDING}}) var<{{WEIGHT_SPACE}}> {{WEIGHTS}}: array<{{WEIGHT_SLOT}}, {{WEIGHT_MATS}}>;
