// The benchmark's FMA ceiling: each invocation runs four independent vec4 fma chains for ITERATIONS
// steps (no memory traffic inside the loop), so the measured rate is what the adapter's ALUs give a
// WGSL kernel, in f32 or, with SCALAR f16 (and `enable f16;`), in half precision. The result is stored
// so the loop cannot be removed.
{{ENABLE}}
const ITERATIONS: u32 = {{ITERATIONS}}u;
alias Lanes = vec4<{{SCALAR}}>;

@group(0) @binding(0) var<storage, read_write> sink: array<vec4f>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3u) {
    let seed = {{SCALAR}}(f32(gid.x) * 1e-7);
    var a0 = Lanes(seed);
    var a1 = Lanes(seed + 1.0);
    var a2 = Lanes(seed + 2.0);
    var a3 = Lanes(seed + 3.0);
    let scale = Lanes(0.999, 0.998, 0.997, 0.996);
    let offset = Lanes(1e-3);
    for (var i = 0u; i < ITERATIONS; i++) {
        a0 = fma(a0, scale, offset);
        a1 = fma(a1, scale, offset);
        a2 = fma(a2, scale, offset);
        a3 = fma(a3, scale, offset);
    }
    sink[gid.x] = vec4f(a0 + a1 + a2 + a3);
}
