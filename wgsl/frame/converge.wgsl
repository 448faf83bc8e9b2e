// The denoised frame of an n-sample mean, blended with that mean: out = mix(denoised, mean, n / (n + k))
// with k = max(CONVERGE_SPP, CONVERGE_SCALE / n): the denoiser counts as k samples. Inverse-variance
// weights when its error equals that of k samples while the mean's variance falls as 1/n: the denoiser
// leads at low spp and hands over to the samples as they converge. k is large at a few spp, where a
// firefly in the mean would come through any sizeable weight, and CONVERGE_SPP from
// sqrt(CONVERGE_SCALE) spp on (fitted: wgpu_rt/frame/unpack.py). Used by unpack (a frame of n spp)
// and by temporal's converge step (a static view accumulating samples frame after frame).
// #import frame/common.wgsl

override CONVERGE_SPP: f32 = 32.0;
override CONVERGE_SCALE: f32 = 2048.0;

@group(0) @binding(8) var<storage, read> samples_mean: array<f32>;
@group(0) @binding(9) var<storage, read> spp: array<u32>;

fn converged(i: u32, denoised: vec3f) -> vec3f {
    let n = pixel_count();
    let mean = vec3f(sanitize(samples_mean[i]), sanitize(samples_mean[n + i]), sanitize(samples_mean[2u * n + i]));
    let samples = f32(max(spp[i], 1u));
    return mix(denoised, mean, samples / (samples + max(CONVERGE_SPP, CONVERGE_SCALE / samples)));
}
