"""The low band (frame/lowband.py): its device passes against their numpy references at sizes that are
not multiples of 2, 4 or the 8×8 tile, the references against hand-worked values, the level rule, the
CLI, and the whole chain on the device against ``denoise()``."""

import numpy as np
import pytest
from parity import check_parity

from wgpu_rt.errors import WgpuRtError
from wgpu_rt.frame.lowband import (LOW_BAND_MAX_SPP, LOW_BAND_MIN_SIDE, LowBandPass, bilinear_up, fewest_samples,
                                   low_band_levels, transfer_low_band, uses_low_band)
from wgpu_rt.frame.pack import (NO_BALANCE, DepthMaxPass, PackLevelPass, WhiteBalancePass, block_mean,
                                pack_denoiser_input, pack_level_input, white_balance_gains)
from wgpu_rt.frame.planes import write_plane
from wgpu_rt.passes import ALBEDO, DEPTH, NORMAL, RADIANCE, SPP, FrameBuffers

SIZES = [(21, 13), (24, 16), (9, 30), (1, 1)]   # (W, H): odd, even, a tall strip, one pixel


def random_planes(rng, width, height):
    color = rng.exponential(2.0, (height, width, 3)).astype(np.float32)
    albedo = rng.uniform(0, 1, (height, width, 3)).astype(np.float32)
    normal = rng.normal(size=(height, width, 3)).astype(np.float32)
    depth = rng.uniform(0.5, 30, (height, width)).astype(np.float32)
    depth[rng.uniform(size=(height, width)) < 0.2] = 0.0
    spp = rng.integers(0, 9, (height, width)).astype(np.uint32)
    return color, albedo, normal, depth, spp


def pack_level_on_gpu(gpu, width, height, factor, color, albedo, normal, depth, spp):
    buffers = FrameBuffers(gpu, width, height)
    for spec, image in ((RADIANCE, color), (ALBEDO, albedo), (NORMAL, normal), (DEPTH, depth), (SPP, spp)):
        write_plane(buffers, spec, image)
    depth_max, balance = DepthMaxPass(gpu, width, height), WhiteBalancePass(gpu, width, height)
    pack = PackLevelPass(gpu, width, height, depth_max.result, balance.result, factor)
    encoder = gpu.device.create_command_encoder()
    for step in (depth_max, balance, pack):
        step.execute(encoder, buffers)
    gpu.device.queue.submit([encoder.finish()])
    level_width, level_height = pack.size
    return gpu.read(pack.result, np.float32, (11, level_height, level_width))


@pytest.mark.parametrize("factor", [2, 4])
@pytest.mark.parametrize("width,height", SIZES)
def test_pack_level_matches_reference(gpu, width, height, factor):
    inputs = random_planes(np.random.default_rng(width * 100 + height), width, height)
    check_parity(None, lambda *a: pack_level_input(*a, factor=factor),
                 lambda *a: pack_level_on_gpu(gpu, width, height, factor, *a),
                 atol=1e-5, rtol=1e-5, inputs=inputs, name=f"pack_denoiser_level {width}x{height} /{factor}")


@pytest.mark.parametrize("poison", [np.nan, np.inf, -np.inf, 3e38])
def test_pack_level_never_emits_non_finite(gpu, poison):
    rng = np.random.default_rng(4)
    color, albedo, normal, depth, spp = random_planes(rng, 21, 13)
    for plane in (color, albedo, normal, depth):
        plane[rng.uniform(size=plane.shape) < 0.2] = poison
    out = pack_level_on_gpu(gpu, 21, 13, 2, color, albedo, normal, depth, spp)
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out, pack_level_input(color, albedo, normal, depth, spp), atol=1e-5, rtol=1e-5)


def test_pack_level_reference_by_hand():
    """A 3×1 frame: the first half pixel averages two pixels, the second holds the odd one alone."""
    color = np.array([[[1.0, 2.0, 0.0], [3.0, 2.0, np.nan], [5.0, 5.0, 5.0]]], np.float32)
    albedo = np.ones((1, 3, 3), np.float32)
    normal = np.array([[[1, 0, 0], [-1, 0, 0], [0, 1, 0]]], np.float32)   # the first two cancel
    depth = np.array([[2.0, 4.0, 8.0]], np.float32)
    x = pack_level_input(color, albedo, normal, depth, np.array([[1, 3, 4]]), balance=NO_BALANCE)
    assert x.shape == (11, 1, 2)
    np.testing.assert_allclose(np.expm1(x[:3, 0, 0]) * 1.01, [2.0, 2.0, 0.0], rtol=1e-6)
    gains = white_balance_gains(color, albedo)                                 # the full frame's, by default
    np.testing.assert_allclose(np.expm1(pack_level_input(color, albedo, normal, depth)[:3, 0, 0]) * 1.01 * gains,
                               [2.0, 2.0, 0.0], rtol=1e-6)
    np.testing.assert_allclose(x[6:9, 0, 0], [0.5, 0.5, 0.5])            # cancelled normals pack as 0
    np.testing.assert_allclose(x[6:9, 0, 1], [0.5, 1.0, 0.5])
    np.testing.assert_allclose(x[9, 0], [3 / 8, 1.0])                    # divided by the frame's max depth
    np.testing.assert_allclose(x[10, 0], [0.5, 0.5])                     # 1 + 3 samples, then 4
    quarter = pack_level_input(color, albedo, normal, depth, np.array([[1, 3, 4]]), factor=4)
    np.testing.assert_allclose(quarter[10], [[1 / np.sqrt(8)]])          # one block of all three


def low_band_on_gpu(gpu, width, height, denoised, coarse, spp, exposure=None):
    """One LowBandPass on a given level: its denoised radiance, the coarser level's radiance, and its
    sample counts packed as pack_denoiser does (the pass reads w from the 1/sqrt(spp) plane); ``exposure``:
    the frame's exposure scale (None: the pass's default)."""
    fine_input = pack_denoiser_input(np.zeros_like(denoised), np.zeros_like(denoised), np.zeros_like(denoised),
                                     np.zeros(denoised.shape[:2], np.float32), spp)
    buffers = [gpu.storage(array.nbytes) for array in (denoised, coarse, fine_input)]
    for buffer, array in zip(buffers, (denoised.transpose(2, 0, 1), coarse.transpose(2, 0, 1), fine_input)):
        gpu.device.queue.write_buffer(buffer, 0, np.ascontiguousarray(array, np.float32))
    scale = None if exposure is None else gpu.upload(np.array([1, 1, 1, exposure], np.float32), label="exposure")
    encoder = gpu.device.create_command_encoder()
    LowBandPass(gpu, width, height, scale).execute(encoder, *buffers)
    gpu.device.queue.submit([encoder.finish()])
    return gpu.read(buffers[0], np.float32, (3, height, width)).transpose(1, 2, 0)


@pytest.mark.parametrize("width,height", SIZES)
def test_low_band_matches_reference(gpu, width, height):
    rng = np.random.default_rng(width + 7 * height)
    half = ((height + 1) // 2, (width + 1) // 2)
    inputs = (rng.exponential(1.0, (height, width, 3)).astype(np.float32),
              rng.exponential(1.0, (*half, 3)).astype(np.float32),
              rng.integers(0, 6, (height, width)).astype(np.uint32))
    check_parity(None, transfer_low_band, lambda *a: low_band_on_gpu(gpu, width, height, *a),
                 atol=1e-5, rtol=1e-5, inputs=inputs, name=f"low band {width}x{height}")


def test_low_band_scales_its_epsilon_with_the_frame_exposure(gpu):
    """ε is LOW_BAND_EPSILON times how much brighter than pack.STEPS_KEY the frame is: a dark frame with its
    exposure scaled alike moves as the frame itself does (with ε fixed it does not), on the device as by the
    reference."""
    rng = np.random.default_rng(6)
    denoised = rng.exponential(0.01, (16, 20, 3)).astype(np.float32)
    coarse = (2.0 * rng.exponential(0.01, (8, 10, 3))).astype(np.float32)
    spp, scale = np.ones((16, 20), np.uint32), np.float32(2.0 ** -12)
    check_parity(None, transfer_low_band, lambda *a: low_band_on_gpu(gpu, 20, 16, *a), atol=1e-5, rtol=1e-5,
                 inputs=[denoised * scale, coarse * scale, spp, 0.5 * scale], name="low band with an exposure")
    moved = transfer_low_band(denoised, coarse, spp, 0.5)
    np.testing.assert_allclose(transfer_low_band(denoised * scale, coarse * scale, spp, 0.5 * scale) / scale, moved,
                               rtol=1e-4)
    assert not np.allclose(transfer_low_band(denoised * scale, coarse * scale, spp, 0.5) / scale, moved, rtol=1e-2)


def test_low_band_never_emits_non_finite(gpu):
    """Radiance at f32's max and 0 on either level."""
    rng = np.random.default_rng(5)
    denoised = rng.exponential(1.0, (13, 21, 3)).astype(np.float32)
    coarse = rng.exponential(1.0, (7, 11, 3)).astype(np.float32)
    for image in (denoised, coarse):
        image[rng.uniform(size=image.shape) < 0.2] = np.finfo(np.float32).max
        image[rng.uniform(size=image.shape) < 0.1] = 0.0
    spp = np.ones((13, 21), np.uint32)
    out = low_band_on_gpu(gpu, 21, 13, denoised, coarse, spp)
    assert np.all(np.isfinite(out)) and out.min() >= 0
    np.testing.assert_allclose(out, transfer_low_band(denoised, coarse, spp), rtol=1e-5,
                               atol=np.finfo(np.float32).tiny)   # NVIDIA flushes subnormal results to 0


def test_transfer_low_band_by_hand():
    """Flat images: the ratio of the two levels' blocks, moved by w = 1/spp; a constant stays constant."""
    denoised = np.full((8, 8, 3), 2.0, np.float32)
    half = np.full((4, 4, 3), 3.0, np.float32)
    eps = 1e-3
    np.testing.assert_allclose(transfer_low_band(denoised, half, 1), 2.0 * (3 + eps) / (2 + eps), rtol=1e-6)
    np.testing.assert_allclose(transfer_low_band(denoised, half, 4), 2.0 * (0.25 * 3 + 0.75 * 2 + eps) / (2 + eps),
                               rtol=1e-6)
    np.testing.assert_allclose(transfer_low_band(denoised, denoised[::2, ::2], 1), denoised, rtol=1e-6)
    # the weight is a low band too: a checkerboard sample map moves every pixel by its mean 1/spp
    counts = np.where(np.indices((8, 8)).sum(0) % 2, 1, 16)
    w = (1 + 1 / 16) / 2
    np.testing.assert_allclose(transfer_low_band(denoised, half, counts), 2.0 * (w * 3 + (1 - w) * 2 + eps) / (2 + eps),
                               rtol=1e-6)
    # F's detail above the quarter band is kept: a checkerboard on a flat half image comes back as it was
    checker = (1 + (np.indices((8, 8)).sum(0) % 2))[..., None].repeat(3, 2).astype(np.float32)
    np.testing.assert_allclose(transfer_low_band(checker, np.full((4, 4, 3), 1.5, np.float32), 1), checker, rtol=1e-3)


def test_block_mean_and_bilinear_up_by_hand():
    image = np.arange(5, dtype=np.float32).reshape(1, 5, 1)
    np.testing.assert_allclose(block_mean(image, 2)[0, :, 0], [0.5, 2.5, 4.0])       # the odd edge alone
    up = bilinear_up(np.array([[[0.0], [4.0]]]), 4, (1, 8))[0, :, 0]
    np.testing.assert_allclose(up, [0, 0, 0.5, 1.5, 2.5, 3.5, 4, 4])                 # clamped at the edges


def test_uses_low_band_and_its_levels():
    assert uses_low_band(LOW_BAND_MIN_SIDE, 1080) and not uses_low_band(LOW_BAND_MIN_SIDE - 1, 1080)
    assert uses_low_band(8, 8, True) and not uses_low_band(1920, 1080, False)
    with pytest.raises(WgpuRtError, match="low_band"):
        uses_low_band(64, 64, "on")
    side = LOW_BAND_MIN_SIDE
    assert [low_band_levels(s, s) for s in (side - 1, side, 2 * side - 2, 2 * side - 1, 8 * side)] == [0, 1, 1, 2, 2]
    assert low_band_levels(1920, 1080) == 2 and low_band_levels(8, 8, True) == 1 and low_band_levels(1920, 1080, False) == 0
    # auto leaves out frames whose every pixel holds LOW_BAND_MAX_SPP samples or more; "on" does not
    assert low_band_levels(1920, 1080, None, LOW_BAND_MAX_SPP - 1) == 2
    assert low_band_levels(1920, 1080, None, LOW_BAND_MAX_SPP) == 0 and low_band_levels(8, 8, True, 1024) == 1


def test_fewest_samples():
    counts = np.full((4, 5, 1), 32.0)
    counts[2, 3] = 3
    assert fewest_samples(counts) == 3 and fewest_samples(16) == 16
    counts[0, 0] = np.nan   # a non-finite count is no samples
    assert fewest_samples(counts) == 0


def test_denoise_leaves_the_low_band_out_from_16_samples_everywhere(monkeypatch):
    """``denoise()`` with low_band None runs the coarser levels unless every pixel holds
    LOW_BAND_MAX_SPP samples; one pixel short is enough to keep them."""
    from wgpu_rt.frame import denoise as denoise_module

    levels_run = []
    monkeypatch.setattr(denoise_module, "low_band_denoise", lambda *a: levels_run.append(a[7]) or a[1])
    from wgpu_rt.frame import lowband
    monkeypatch.setattr(lowband, "LOW_BAND_MIN_SIDE", 8)
    rng = np.random.default_rng(2)
    color, albedo, normal, depth, _ = random_planes(rng, 12, 10)

    def model(x):
        return np.zeros((1, 3, *x.shape[2:]), np.float32)

    spp = np.full((10, 12), LOW_BAND_MAX_SPP)
    denoise_module.denoise(model, color, albedo, normal, depth, spp, chroma=False)
    spp[4, 4] = LOW_BAND_MAX_SPP - 1
    denoise_module.denoise(model, color, albedo, normal, depth, spp, chroma=False)
    assert levels_run == [1]


@pytest.mark.parametrize("command", ["render", "denoise"])
def test_cli_help_states_the_auto_rule(command):
    """``--low-band``'s help names the side from which "auto" takes the low band, as the code does."""
    from wgpu_rt.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices[command]
    help_text = " ".join(next(a for a in sub._actions if a.dest == "low_band").help.split())
    assert f"at least {LOW_BAND_MIN_SIDE} pixels a side, unless every pixel holds {LOW_BAND_MAX_SPP} samples" in help_text


def test_denoise_command_takes_the_low_band_setting(gpu, tmp_path):
    """``wgpu-rt denoise --low-band on|off`` writes what ``denoise()`` gives with that setting (auto: off
    on this small image)."""
    from wgpu_rt.cli import main
    from wgpu_rt.frame.denoise import denoise, load_model
    from wgpu_rt.io import AUX_SAMPLES_ATTRIBUTE, read_exr, write_exr

    rng = np.random.default_rng(6)
    color, albedo, normal, depth, _ = random_planes(rng, 22, 17)
    write_exr(tmp_path / "in.exr", color, {"albedo": albedo, "normal": normal, "depth": depth[..., None]},
              attributes={AUX_SAMPLES_ATTRIBUTE: 4})   # an aux-pass albedo: read as it is
    model = load_model("denoiser")
    written = {}
    for setting in ("auto", "on", "off"):
        out = tmp_path / f"{setting}.exr"
        assert main(["denoise", str(tmp_path / "in.exr"), "--out", str(out), "--low-band", setting]) == 0
        written[setting] = read_exr(out)["color"]
    for setting, low_band in (("on", True), ("off", False)):
        np.testing.assert_allclose(written[setting], denoise(model, color, albedo, normal, depth, low_band=low_band),
                                   rtol=1e-4, atol=1e-5)
    np.testing.assert_array_equal(written["auto"], written["off"])
    assert not np.allclose(written["on"], written["off"], rtol=1e-3, atol=1e-4)
