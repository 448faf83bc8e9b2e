"""The colour balance held to the samples (frame/chroma.py): the device pass against its numpy reference
at sizes that are not multiples of the 4×4 block or the 8×8 tile, poisoned inputs, the reference against
hand-worked cases, the option and the flags."""

import numpy as np
import pytest
from parity import check_parity, run_frame_pass

from wgpu_rt.frame.chroma import RATIO_LIMIT, SHARE_EPSILON, ChromaPass, chroma_ratios, match_sample_chroma
from wgpu_rt.frame.planes import DENOISED
from wgpu_rt.passes import RADIANCE

SIZES = [(21, 13), (24, 16), (9, 30), (1, 1), (40, 37)]   # (W, H); 40×37: more blocks than the 7×7 window


def chroma_on_gpu(gpu, width, height, denoised, color, exposure=None):
    scale = None if exposure is None else gpu.upload(np.array([1, 1, 1, exposure], np.float32), label="exposure")
    buffers = run_frame_pass(gpu, ChromaPass(gpu, width, height, scale), width, height,
                             {RADIANCE: color, DENOISED: denoised})
    return gpu.read(buffers.get(DENOISED), np.float32, (3, height, width)).transpose(1, 2, 0)


def biased_pair(rng, width, height):
    """A denoised frame and a noisy samples' mean around a differently coloured truth."""
    truth = rng.uniform(0.1, 2.0, (height, width, 1)) * np.array([0.6, 1.0, 0.3])
    denoised = (truth * np.array([1.3, 0.8, 1.1])).astype(np.float32)
    color = (truth * rng.exponential(1.0, (height, width, 3))).astype(np.float32)
    return denoised, color


@pytest.mark.parametrize("width,height", SIZES)
def test_chroma_matches_reference(gpu, width, height):
    inputs = biased_pair(np.random.default_rng(width * 31 + height), width, height)
    ours, reference = check_parity(None, match_sample_chroma, lambda *a: chroma_on_gpu(gpu, width, height, *a),
                                   atol=1e-5, rtol=1e-5, inputs=inputs, name=f"chroma {width}x{height}")
    if width * height > 100:
        assert not np.allclose(reference, inputs[0], rtol=1e-3)   # the case does move colours


def test_chroma_scales_its_epsilon_with_the_frame_exposure(gpu):
    """ε is SHARE_EPSILON times the frame's exposure scale: a dark frame with its exposure scaled alike is
    held as the frame itself is (with ε fixed it is not), on the device as by the reference."""
    denoised, color = biased_pair(np.random.default_rng(3), 24, 16)
    denoised[:8] *= 1e-4                                           # a near-black half, where ε matters
    color[:8] *= 1e-4
    exposure, scale = 1.5, np.float32(2.0 ** -10)
    check_parity(None, match_sample_chroma, lambda *a: chroma_on_gpu(gpu, 24, 16, *a), atol=1e-5, rtol=1e-5,
                 inputs=[denoised * scale, color * scale, exposure * scale], name="chroma with an exposure")
    held = match_sample_chroma(denoised, color, exposure)
    np.testing.assert_allclose(match_sample_chroma(denoised * scale, color * scale, exposure * scale) / scale, held,
                               rtol=1e-4, atol=1e-12)
    assert not np.allclose(match_sample_chroma(denoised * scale, color * scale, exposure) / scale, held, rtol=1e-2)


@pytest.mark.parametrize("poison", [np.nan, np.inf, -np.inf, -1.0, np.finfo(np.float32).max])
def test_chroma_never_emits_non_finite(gpu, poison):
    rng = np.random.default_rng(8)
    denoised, color = biased_pair(rng, 21, 13)
    for image in (denoised, color):
        image[rng.uniform(size=image.shape) < 0.15] = poison
    out = chroma_on_gpu(gpu, 21, 13, denoised, color)
    reference = match_sample_chroma(denoised, color)
    assert np.all(np.isfinite(out)) and out.min() >= 0 and np.all(np.isfinite(reference))
    np.testing.assert_allclose(out, reference, rtol=1e-5, atol=1e-6)


def test_chroma_by_hand():
    flat = np.ones((8, 8, 3), np.float32)
    # samples that agree with the denoised frame change nothing
    np.testing.assert_allclose(match_sample_chroma(flat, flat), flat, rtol=1e-6)
    # noise-free samples with a green cast: their chromaticity is taken, the brightness (sum) stays F's
    cast = np.broadcast_to(np.array([0.5, 2.0, 0.5], np.float32), (8, 8, 3))
    expected = 3 * (cast + SHARE_EPSILON) / (3 + 3 * SHARE_EPSILON)
    np.testing.assert_allclose(match_sample_chroma(flat, cast), expected, rtol=1e-6)
    # a slight cast (2 % more green) in noise far larger than it (±100 % per pixel) moves nothing
    checker = np.where(np.indices((8, 8)).sum(0) % 2 == 1, 2.0, 0.0)[..., None] * np.ones(3) - 1
    noisy = (np.array([1.0, 1.02, 1.0]) + checker).astype(np.float32)
    np.testing.assert_allclose(match_sample_chroma(flat, noisy), flat, rtol=1e-6)
    # the same cast with noise ten times smaller is taken whole, bar the noise's own share
    np.testing.assert_allclose(match_sample_chroma(flat, (np.array([1.0, 1.02, 1.0]) + checker / 1000).astype(np.float32)),
                               np.broadcast_to(3 * np.array([1.0, 1.02, 1.0]) / 3.02, (8, 8, 3)), rtol=1e-3)
    # a channel the denoiser nearly lost is scaled up by at most RATIO_LIMIT
    lost = np.broadcast_to(np.array([1.0, 1e-3, 1.0], np.float32), (8, 8, 3))
    assert chroma_ratios(lost, flat)[..., 1].max() == pytest.approx(RATIO_LIMIT)


def test_chroma_keeps_detail_and_edges():
    """A step in brightness whose colour the samples agree with comes back unchanged; the correction is
    a low band: a one-pixel speck in F keeps its size."""
    rng = np.random.default_rng(3)
    step = np.where(np.arange(32) < 16, 0.1, 5.0).astype(np.float32)[None, :, None] * np.ones((32, 1, 3), np.float32)
    np.testing.assert_allclose(match_sample_chroma(step, step), step, rtol=1e-6)
    speck = np.full((32, 32, 3), 0.5, np.float32)
    speck[10, 10] = 4.0
    noisy = (speck * rng.exponential(1.0, speck.shape)).astype(np.float32)
    out = match_sample_chroma(speck, noisy)
    ratio = out / speck
    assert np.abs(ratio[10, 10] - ratio[10, 11]).max() < 0.05   # the speck is scaled as its neighbours


def test_chroma_flag_needs_the_denoiser(tmp_path):
    """The flag is the denoiser's: refused without --denoise, before any output is written."""
    from wgpu_rt.cli import main

    assert main(["render", "cornell", "--size", "8x8", "--spp", "1", "--chroma", "off",
                 "--out", str(tmp_path / "x.exr")]) == 2
    assert not (tmp_path / "x.exr").exists()


def test_denoise_command_takes_the_chroma_setting(gpu, tmp_path):
    """``wgpu-rt denoise --chroma on|off`` writes what ``denoise()`` gives with that setting."""
    from wgpu_rt.cli import main
    from wgpu_rt.frame.denoise import denoise, load_model
    from wgpu_rt.io import AUX_SAMPLES_ATTRIBUTE, read_exr, write_exr

    rng = np.random.default_rng(9)
    denoised, color = biased_pair(rng, 22, 17)
    albedo = rng.uniform(0, 1, (17, 22, 3)).astype(np.float32)
    normal = rng.normal(size=(17, 22, 3)).astype(np.float32)
    depth = rng.uniform(1, 5, (17, 22, 1)).astype(np.float32)
    write_exr(tmp_path / "in.exr", color, {"albedo": albedo, "normal": normal, "depth": depth},
              attributes={AUX_SAMPLES_ATTRIBUTE: 4})   # an aux-pass albedo: read as it is
    model = load_model("denoiser")
    written = {}
    for setting in ("on", "off"):
        out = tmp_path / f"{setting}.exr"
        assert main(["denoise", str(tmp_path / "in.exr"), "--out", str(out), "--chroma", setting]) == 0
        written[setting] = read_exr(out)["color"]
        expected = denoise(model, color, albedo, normal, depth, chroma=setting == "on")
        np.testing.assert_allclose(written[setting], expected, rtol=1e-4, atol=1e-5)
    assert not np.allclose(written["on"], written["off"], rtol=1e-3, atol=1e-4)
