// The activation fused into a kernel's epilogue, chosen when the pipeline is created:
// 0 none, 1 ReLU, 2 LeakyReLU(ALPHA), 3 sigmoid, 4 clip to [CLIP_LO, CLIP_HI].
const ACTIVATION: u32 = {{ACTIVATION}}u;
const ALPHA: f32 = {{ALPHA}};
const CLIP_LO: f32 = {{CLIP_LO}};
const CLIP_HI: f32 = {{CLIP_HI}};

fn activate(v: vec4f) -> vec4f {
    if (ACTIVATION == 1u) {
        return max(v, vec4f(0.0));
    }
    if (ACTIVATION == 2u) {
        return select(v * ALPHA, v, v >= vec4f(0.0));
    }
    if (ACTIVATION == 3u) {
        return 1.0 / (1.0 + exp(-v));
    }
    if (ACTIVATION == 4u) {
        return clamp(v, vec4f(CLIP_LO), vec4f(CLIP_HI));
    }
    return v;
}
