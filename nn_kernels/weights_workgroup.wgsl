// Weight blocks staged in workgroup memory, one input block's worth at a time: conv3x3_staged.wgsl
// calls stage_{{WEIGHT}}s(cb, invocation) between the two barriers that stage input block cb, so the
// STAGED_MATS blocks of window {{WEIGHT}} that block needs (3×3 taps × the window's output blocks) are
// loaded once per workgroup and every invocation then reads them from workgroup memory, all lanes the
// same address (a broadcast). The window starts at block {{WINDOW_BASE}} of the binding {{WEIGHTS}}
// (weight_binding.wgsl); STAGED_MATS is declared once beside these (kernels.ConvFamilyKernel).
var<workgroup> {{WEIGHT}}_staged: array<mat4x4f, STAGED_MATS>;
var<private> {{WEIGHT}}_staged_from: i32;  // the window's first block staged now

fn stage_{{WEIGHT}}s(cb: i32, invocation: i32) {
    {{WEIGHT}}_staged_from = cb * STAGED_MATS;
    if (invocation < STAGED_MATS) {
        {{WEIGHT}}_staged[invocation] = {{WEIGHTS}}[{{WINDOW_BASE}} + {{WEIGHT}}_staged_from + invocation];
    }
}

fn {{WEIGHT}}_block(index: i32, lane: WeightLane) -> mat4x4f {
    return {{WEIGHT}}_staged[index - {{WEIGHT}}_staged_from];
}
