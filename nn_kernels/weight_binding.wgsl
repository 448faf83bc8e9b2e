// A binding of weight blocks (mat4x4: 4 input × 4 output channels) for the fetch functions of
// weights_subgroup.wgsl / weights_uniform.wgsl: a uniform block when it fits, else read-only storage.
@group(0) @binding({{WEIGHT_BINDING}}) var<{{WEIGHT_SPACE}}> {{WEIGHTS}}: array<mat4x4f, {{WEIGHT_MATS}}>;
