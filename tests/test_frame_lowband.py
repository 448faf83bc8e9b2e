"""The half-resolution low band (frame/lowband.py): its two device passes against their numpy references
at sizes that are not multiples of 2, 4 or the 8×8 tile, the references against hand-worked values, the
auto rule, and the frame pipeline against ``denoise()``."""

import numpy as np
import pytest
from parity import check_parity

from wgpu_rt.errors import WgpuRtError
from wgpu_rt.frame.lowband import LOW_BAND_MIN_SIDE, LowBandPass, bilinear_up, transfer_low_band, uses_low_band
from wgpu_rt.frame.pack import DepthMaxPass, PackHalfDenoiserPass, block_mean, pack_half_denoiser_input
from wgpu_rt.frame.planes import DENOISED, write_plane
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


def pack_half_on_gpu(gpu, width, height, color, albedo, normal, depth, spp):
    buffers = FrameBuffers(gpu, width, height)
    for spec, image in ((RADIANCE, color), (ALBEDO, albedo), (NORMAL, normal), (DEPTH, depth), (SPP, spp)):
        write_plane(buffers, spec, image)
    depth_max = DepthMaxPass(gpu, width, height)
    pack_half = PackHalfDenoiserPass(gpu, width, height, depth_max.result)
    encoder = gpu.device.create_command_encoder()
    depth_max.execute(encoder, buffers)
    pack_half.execute(encoder, buffers)
    gpu.device.queue.submit([encoder.finish()])
    half_width, half_height = pack_half.size
    return gpu.read(pack_half.result, np.float32, (11, half_height, half_width))


@pytest.mark.parametrize("width,height", SIZES)
def test_pack_half_matches_reference(gpu, width, height):
    inputs = random_planes(np.random.default_rng(width * 100 + height), width, height)
    check_parity(None, pack_half_denoiser_input, lambda *a: pack_half_on_gpu(gpu, width, height, *a),
                 atol=1e-5, rtol=1e-5, inputs=inputs, name=f"pack_denoiser_half {width}x{height}")


@pytest.mark.parametrize("poison", [np.nan, np.inf, -np.inf, 3e38])
def test_pack_half_never_emits_non_finite(gpu, poison):
    rng = np.random.default_rng(4)
    color, albedo, normal, depth, spp = random_planes(rng, 21, 13)
    for plane in (color, albedo, normal, depth):
        plane[rng.uniform(size=plane.shape) < 0.2] = poison
    out = pack_half_on_gpu(gpu, 21, 13, color, albedo, normal, depth, spp)
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out, pack_half_denoiser_input(color, albedo, normal, depth, spp), atol=1e-5, rtol=1e-5)


def test_pack_half_reference_by_hand():
    """A 3×1 frame: the first half pixel averages two pixels, the second holds the odd one alone."""
    color = np.array([[[1.0, 2.0, 0.0], [3.0, 2.0, np.nan], [5.0, 5.0, 5.0]]], np.float32)
    albedo = np.ones((1, 3, 3), np.float32)
    normal = np.array([[[1, 0, 0], [-1, 0, 0], [0, 1, 0]]], np.float32)   # the first two cancel
    depth = np.array([[2.0, 4.0, 8.0]], np.float32)
    x = pack_half_denoiser_input(color, albedo, normal, depth, np.array([[1, 3, 4]]))
    assert x.shape == (11, 1, 2)
    np.testing.assert_allclose(np.expm1(x[:3, 0, 0]) * 1.01, [2.0, 2.0, 0.0], rtol=1e-6)
    np.testing.assert_allclose(x[6:9, 0, 0], [0.5, 0.5, 0.5])            # cancelled normals pack as 0
    np.testing.assert_allclose(x[6:9, 0, 1], [0.5, 1.0, 0.5])
    np.testing.assert_allclose(x[9, 0], [3 / 8, 1.0])                    # divided by the frame's max depth
    np.testing.assert_allclose(x[10, 0], [0.5, 0.5])                     # 1 + 3 samples, then 4


def low_band_on_gpu(gpu, width, height, denoised, half_output, half_albedo, spp):
    """LowBandPass on a given denoised frame and half-resolution network output (log1p irradiance)."""
    buffers = FrameBuffers(gpu, width, height)
    write_plane(buffers, DENOISED, denoised)
    write_plane(buffers, SPP, spp)
    half_height, half_width = half_output.shape[1:]
    half_input = np.zeros((11, half_height, half_width), np.float32)
    half_input[3:6] = half_albedo.transpose(2, 0, 1)
    half_input_buffer = gpu.storage(half_input.nbytes)
    output_buffer = gpu.storage(half_output.nbytes)
    gpu.device.queue.write_buffer(half_input_buffer, 0, half_input)
    gpu.device.queue.write_buffer(output_buffer, 0, np.ascontiguousarray(half_output, np.float32))
    low_band = LowBandPass(gpu, width, height, half_input_buffer)
    encoder = gpu.device.create_command_encoder()
    low_band.execute(encoder, buffers, output_buffer)
    gpu.device.queue.submit([encoder.finish()])
    return buffers.read(DENOISED.name).transpose(1, 2, 0)


def low_band_reference(denoised, half_output, half_albedo, spp):
    from wgpu_rt.frame.unpack import unpack_denoiser_output

    return transfer_low_band(denoised, unpack_denoiser_output(half_output, half_albedo), spp)


@pytest.mark.parametrize("width,height", SIZES)
def test_low_band_matches_reference(gpu, width, height):
    rng = np.random.default_rng(width + 7 * height)
    half = ((height + 1) // 2, (width + 1) // 2)
    inputs = (rng.exponential(1.0, (height, width, 3)).astype(np.float32),
              rng.uniform(-0.5, 3.0, (3, *half)).astype(np.float32),
              rng.uniform(0, 1, (*half, 3)).astype(np.float32),
              rng.integers(0, 6, (height, width)).astype(np.uint32))
    check_parity(None, low_band_reference, lambda *a: low_band_on_gpu(gpu, width, height, *a),
                 atol=1e-5, rtol=1e-5, inputs=inputs, name=f"low band {width}x{height}")


def test_low_band_never_emits_non_finite(gpu):
    """Radiance at f32's max, network outputs beyond the unpack's clamp, NaN and ±Inf."""
    rng = np.random.default_rng(5)
    denoised = rng.exponential(1.0, (13, 21, 3)).astype(np.float32)
    denoised[rng.uniform(size=denoised.shape) < 0.2] = np.finfo(np.float32).max
    denoised[rng.uniform(size=denoised.shape) < 0.1] = 0.0
    half_output = rng.uniform(0, 3, (3, 7, 11)).astype(np.float32)
    for poison in (1e4, np.nan, np.inf, -np.inf):
        half_output[rng.uniform(size=half_output.shape) < 0.1] = poison
    albedo = rng.uniform(0, 1, (7, 11, 3)).astype(np.float32)
    spp = np.ones((13, 21), np.uint32)
    out = low_band_on_gpu(gpu, 21, 13, denoised, half_output, albedo, spp)
    assert np.all(np.isfinite(out)) and out.min() >= 0
    np.testing.assert_allclose(out, low_band_reference(denoised, half_output, albedo, spp), rtol=1e-5)


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


def test_uses_low_band():
    assert uses_low_band(LOW_BAND_MIN_SIDE, 1080) and not uses_low_band(LOW_BAND_MIN_SIDE - 1, 1080)
    assert uses_low_band(8, 8, True) and not uses_low_band(1920, 1080, False)
    with pytest.raises(WgpuRtError, match="low_band"):
        uses_low_band(64, 64, "on")


@pytest.mark.parametrize("command", ["render", "denoise"])
def test_cli_help_states_the_auto_rule(command):
    """``--low-band``'s help names the side from which "auto" takes the low band, as the code does."""
    from wgpu_rt.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices[command]
    help_text = " ".join(next(a for a in sub._actions if a.dest == "low_band").help.split())
    assert f"at least {LOW_BAND_MIN_SIDE} pixels a side" in help_text


def test_denoise_command_takes_the_low_band_setting(gpu, tmp_path):
    """``wgpu-rt denoise --low-band on|off`` writes what ``denoise()`` gives with that setting (auto: off
    on this small image)."""
    from wgpu_rt.cli import main
    from wgpu_rt.frame.denoise import denoise, load_model
    from wgpu_rt.io import read_exr, write_exr

    rng = np.random.default_rng(6)
    color, albedo, normal, depth, _ = random_planes(rng, 22, 17)
    write_exr(tmp_path / "in.exr", color, {"albedo": albedo, "normal": normal, "depth": depth[..., None]})
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
