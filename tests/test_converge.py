"""The converge pass (wgpu_rt/frame/converge.py): its kernel against the numpy reference, and what the
rule promises: a converged mean takes over from a biased denoiser (up to the cap), a mean whose two
parts disagree (a firefly) does not, a few samples barely count, and nothing non-finite comes out."""

import numpy as np
import pytest
from parity import check_parity

from wgpu_rt.frame.adaptive import HALF_RADIANCE
from wgpu_rt.frame.converge import CONVERGE_CAP_SCALE, CONVERGE_RADIUS, CONVERGED, HALF_SPP, ConvergePass, converge
from wgpu_rt.frame.planes import DENOISED, write_plane
from wgpu_rt.passes import RADIANCE, SPP, FrameBuffers


def converge_on_gpu(gpu, denoised, mean, half, spp, half_spp):
    height, width = spp.shape
    buffers = FrameBuffers(gpu, width, height)
    for plane, image in ((DENOISED, denoised), (RADIANCE, mean), (HALF_RADIANCE, half)):
        write_plane(buffers, plane, image)
    write_plane(buffers, SPP, spp.astype(np.uint32))
    write_plane(buffers, HALF_SPP, half_spp.astype(np.uint32))
    encoder = gpu.device.create_command_encoder()
    ConvergePass(gpu, width, height).execute(encoder, buffers)
    gpu.device.queue.submit([encoder.finish()])
    return buffers.read(CONVERGED.name).transpose(1, 2, 0)


def random_frame(shape, seed=0):
    """A mean, its copy after part of the samples (far off where a firefly came later), a denoised
    frame near the mean, per-pixel sample counts 1–300 and the copy's counts (some pixels with no
    samples after it)."""
    rng = np.random.default_rng(seed)
    height, width = shape
    mean = rng.gamma(2.0, 0.3, (height, width, 3)).astype(np.float32)
    off = np.where(rng.random((height, width, 1)) < 0.1, 0.9, 0.05) * rng.uniform(-1, 1, mean.shape)
    half = (mean * (1 + off)).astype(np.float32)
    denoised = (mean * rng.uniform(0.7, 1.3, mean.shape)).astype(np.float32)
    spp = rng.integers(1, 300, (height, width))
    half_spp = np.where(rng.random((height, width)) < 0.03, spp, spp // 2)
    return denoised, mean, half, spp, half_spp


@pytest.mark.parametrize("shape", [(16, 16), (13, 21), (3, 5)])
def test_kernel_matches_reference(gpu, shape):
    denoised, mean, half, spp, half_spp = random_frame(shape)
    check_parity(None, lambda *x: converge(*x[:2], spp, x[2], half_spp),
                 lambda *x: converge_on_gpu(gpu, *x, spp, half_spp),
                 inputs=[denoised, mean, half], atol=1e-5, rtol=1e-4, name=f"converge {shape}")


def test_non_finite_inputs_give_finite_output_as_the_reference(gpu):
    denoised, mean, half, spp, half_spp = random_frame((16, 16), seed=1)
    half_spp[:] = spp // 2
    denoised[0, 0], mean[1, 1], half[2, 2] = np.nan, np.inf, -np.inf
    mean[9, 9] = 2e19        # squares overflow f32
    half[12, 12] = 3e38
    ours = converge_on_gpu(gpu, denoised, mean, half, spp, half_spp)
    assert np.all(np.isfinite(ours)) and np.all(ours >= 0)
    np.testing.assert_allclose(ours, converge(denoised, mean, spp, half, half_spp), rtol=1e-4, atol=1e-5)


def test_a_converged_mean_takes_over_a_biased_denoiser_up_to_the_cap():
    """The two parts of the mean agree closely and the denoised frame is 20 % off: the mean's share
    is the cap, n² / (n² + CAP_SCALE)."""
    mean = np.full((8, 8, 3), 0.5, np.float32)
    for n in (4, 64, 256):
        spp = np.full((8, 8), n)
        out = converge(mean * 1.2, mean, spp, mean * 1.001, spp // 2)
        share = (mean * 1.2 - out) / (mean * 0.2)
        np.testing.assert_allclose(share, n * n / (n * n + CONVERGE_CAP_SCALE), rtol=1e-3)


def test_a_firefly_leaves_the_denoised_value():
    """A pixel whose second half brought a firefly (its two parts disagree by as much as the mean
    differs from the denoised frame) keeps almost all of the denoised value however many samples."""
    denoised = np.full((8, 8, 3), 0.5, np.float32)
    mean, half = denoised.copy(), denoised.copy()
    mean[4, 4] = 40.0
    out = converge(denoised, mean, np.full((8, 8), 256), half, np.full((8, 8), 128))
    assert abs(out[4, 4, 0] - 0.5) < 0.05 * (40.0 - 0.5)


def test_a_dark_pixel_is_weighed_as_it_shows_on_screen():
    """A converged black pixel (both parts of its mean 0) among pixels of 0.02 whose mean is still a
    little noisy and whose denoised value is right. The denoiser's 4e-4 at the black pixel is tiny in
    linear terms but shows as 0.03 after (x / (1 + x))^(1/2.2), more than the neighbours' noise shows:
    weighed on screen, the window hands most of that pixel to the mean, where linear sums (which the
    neighbours' noise dominates) handed it none."""
    rng = np.random.default_rng(3)
    n, size = 256, (9, 9)
    denoised = np.full(size + (3,), 0.02, np.float32)
    noise = rng.normal(0.0, 1e-4, size + (3,)).astype(np.float32)
    mean, half = denoised + noise, denoised - noise
    denoised[4, 4], mean[4, 4], half[4, 4] = 4e-4, 0.0, 0.0
    out = converge(denoised, mean, np.full(size, n), half, np.full(size, n // 2))
    assert np.all(1.0 - out[4, 4] / 4e-4 > 0.85)


def test_a_bright_pixel_whose_halves_disagree_does_not_hold_back_its_neighbours():
    """A caustic: one pixel of 586 whose first half read 1172 (the second found nothing), beside pixels
    whose mean has converged (both halves 0.0129) where the denoiser is off (0.19). Its variance used to
    fill every window it fell in, so its neighbours kept the denoised value; weighed by how alike their
    denoised values look on screen (0.81 against 0.47), it no longer counts for them, and the mean takes
    over up to the cap. The bright pixel itself still keeps its denoised value."""
    n, size = 256, (9, 9)
    denoised = np.full(size + (3,), 0.19, np.float32)
    mean = np.full(size + (3,), 0.0129, np.float32)
    half = mean.copy()
    denoised[4, 5], mean[4, 5], half[4, 5] = 1.74, 586.0, 1172.0
    counts, first = np.full(size, n), np.full(size, n // 2)
    share = (denoised[4, 4] - converge(denoised, mean, counts, half, first)[4, 4]) / (0.19 - 0.0129)
    np.testing.assert_allclose(share, n * n / (n * n + CONVERGE_CAP_SCALE), rtol=1e-3)
    before = converge(denoised, mean, counts, half, first, radius=2, on_screen=False, tau=np.inf)
    assert np.all(before[4, 4] > 0.18)
    assert np.all(converge(denoised, mean, counts, half, first)[4, 5] < 2.0)


def test_pixels_without_samples_after_the_copy_keep_the_denoised_value_and_are_left_out():
    """Such a pixel (an adaptive map's pixel that took no extra samples) has no estimate of its mean's
    error: it keeps the denoised value, and its neighbours' averages leave it out (its stale copy would
    otherwise read as a huge error of the mean)."""
    denoised, mean, half, spp, _ = random_frame((8, 8), seed=2)
    np.testing.assert_allclose(converge(denoised, mean, spp, half, spp), denoised, rtol=1e-6, atol=1e-7)
    mean = np.full((8, 8, 3), 0.5, np.float32)
    spp, half_spp = np.full((8, 8), 64), np.full((8, 8), 32)
    half_spp[:, :4] = spp[:, :4]                       # the left half took nothing after the copy
    stale = mean.copy()
    stale[:, :4] = 100.0
    out = converge(mean * 1.2, mean, spp, stale, half_spp)
    np.testing.assert_allclose(out[:, :4], mean[:, :4] * 1.2)
    np.testing.assert_allclose(out[:, 4:], converge(mean * 1.2, mean, spp, mean, spp // 2)[:, 4:], rtol=1e-6)


def test_a_wider_window_keeps_a_right_denoiser_where_the_halves_agree_by_chance():
    """The denoiser is exact and the 16-sample mean is noise (its halves independent draws around the truth).
    Any share of the mean is error; a pixel gets some wherever its window's halves happen to agree. The shipped
    15×15 window (BENCHMARKS.md §43) averages enough pixels that this happens far less than in the 7×7 window
    it replaced: under half the error, and both far below the mean's own."""
    rng = np.random.default_rng(0)
    truth = np.full((64, 64, 3), 0.5, np.float32)
    first, second = rng.normal(0.0, 0.2, (2, 64, 64, 3))
    half, mean = (truth + first).astype(np.float32), (truth + (first + second) / 2).astype(np.float32)
    spp = np.full((64, 64), 16)

    def error(radius):
        return float(np.mean((converge(truth, mean, spp, half, spp // 2, radius=radius) - truth) ** 2))

    assert error(CONVERGE_RADIUS) < 0.5 * error(3) < 0.05 * float(np.mean((mean - truth) ** 2))
