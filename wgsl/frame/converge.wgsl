// The denoised frame of an n-sample mean, blended with that mean: out = mix(denoised, mean,
// n / (n + CONVERGE_SPP)). Inverse-variance weights when the denoiser's error (a bias that stays as n
// grows) equals that of CONVERGE_SPP samples while the mean's variance falls as 1/n: the denoiser
// leads at low spp and hands over to the samples as they converge. Used by unpack (a frame of n spp)
// and by temporal's converge step (a static view accumulating samples frame after frame).
// #import frame/common.wgsl

override CONVERGE_SPP: f32 = 32.0;

@group(0) @binding(8) var<storage, read> samples_mean: array<f32>;
@group(0) @binding(9) var<storage, read> spp: array<u32>;

fn converged(i: u32, denoised: vec3f) -> vec3f {
    let n = pixel_count();
    let mean = vec3f(sanitize(samples_mean[i]), sanitize(samples_mean[n + i]), sanitize(samples_mean[2u * n + i]));
    let samples = f32(spp[i]);
    return mix(denoised, mean, samples / (samples + CONVERGE_SPP));
}
