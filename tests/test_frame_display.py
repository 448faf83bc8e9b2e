"""Unpack (expm1, remodulated by albedo and the white balance) and tonemap passes against their numpy
references, with non-finite stress."""

import re

import numpy as np
import pytest
from parity import check_parity

from wgpu_rt.errors import WgpuRtError
from wgpu_rt.frame.planes import DENOISED, write_plane
from wgpu_rt.frame.tonemap import CURVE_INPUT_MAX, MAX_EXPOSURE_STOPS, TonemapPass, aces_fitted, tonemap
from wgpu_rt.frame.unpack import UnpackPass, unpack_denoiser_output
from wgpu_rt.passes import ALBEDO, FrameBuffers, PlaneSpec
from wgpu_rt.shaders import read_wgsl

H, W = 20, 36
NETWORK_OUTPUT = PlaneSpec("network_output", 3)


def submit(gpu, passes, buffers):
    encoder = gpu.device.create_command_encoder()
    for p in passes:
        p.execute(encoder, buffers)
    gpu.device.queue.submit([encoder.finish()])


BALANCE = np.array([0.5, 1.25, 3.0], np.float32)   # white-balance gains, the last the largest there can be


def unpack_on_gpu(gpu, tensor, albedo, balance=BALANCE):
    buffers = FrameBuffers(gpu, W, H)
    write_plane(buffers, NETWORK_OUTPUT, tensor.transpose(1, 2, 0))
    write_plane(buffers, ALBEDO, albedo)
    encoder = gpu.device.create_command_encoder()
    UnpackPass(gpu, W, H, gpu.upload(balance)).execute(encoder, buffers, NETWORK_OUTPUT)
    gpu.device.queue.submit([encoder.finish()])
    return buffers.read(DENOISED.name).transpose(1, 2, 0)


def random_albedo(seed):
    return np.random.default_rng(seed).uniform(-0.2, 1.2, (H, W, 3)).astype(np.float32)


def test_unpack_matches_reference(gpu):
    tensor = np.random.default_rng(0).uniform(-1, 3, (3, H, W)).astype(np.float32)
    check_parity(None, unpack_denoiser_output, lambda t, a, b: unpack_on_gpu(gpu, t, a, b), atol=1e-6, rtol=3e-5,
                 inputs=[tensor, random_albedo(10), BALANCE], name="unpack")


def test_unpack_matches_reference_over_fp16_range(gpu):
    """Up to log1p(65504) ≈ 11.1: relative accuracy over the whole range the FP16 network emits."""
    tensor = np.random.default_rng(0).uniform(0, np.log1p(65504.0), (3, H, W)).astype(np.float32)
    albedo = random_albedo(11)
    np.testing.assert_allclose(unpack_on_gpu(gpu, tensor, albedo), unpack_denoiser_output(tensor, albedo, BALANCE),
                               rtol=3e-5, atol=1e-6)


def test_unpack_reference_by_hand():
    """expm1 of the clamped log value times the albedo factor (albedo clamped to [0, 1], + 0.01) times the
    channel's white-balance gain; the largest log value times the largest factor and gain stays finite."""
    tensor = np.array([np.log1p(3.0), -2.0, np.nan, np.inf, 1e-9, 200.0], np.float32).reshape(3, 2, 1)
    albedo = np.array([0.5, 2.0, np.nan, -1.0, 0.0, 1.0], np.float32).reshape(3, 2, 1).transpose(1, 2, 0)
    out = unpack_denoiser_output(tensor, albedo, np.array([2.0, 1.0, 3.0], np.float32))
    np.testing.assert_allclose(out.transpose(2, 0, 1).ravel(),
                               [3.0 * 0.51 * 2, 0.0, 0.0, 0.0, 1e-9 * 0.01 * 3, np.expm1(43.0) * 1.01 * 3], rtol=1e-6)
    assert np.all(np.isfinite(out))


@pytest.mark.parametrize("poison", [np.nan, np.inf, -np.inf, 1e30])
def test_unpack_output_is_finite_and_non_negative(gpu, poison):
    rng = np.random.default_rng(1)
    tensor = rng.uniform(-3, 11, (3, H, W)).astype(np.float32)
    albedo = random_albedo(12)
    tensor[rng.uniform(size=tensor.shape) < 0.2] = poison
    albedo[rng.uniform(size=albedo.shape) < 0.2] = poison
    out = unpack_on_gpu(gpu, tensor, albedo)
    assert np.all(np.isfinite(out)) and out.min() >= 0
    np.testing.assert_allclose(out, unpack_denoiser_output(tensor, albedo, BALANCE), rtol=3e-5, atol=1e-6)


def tonemap_on_gpu(gpu, image, **settings):
    buffers = FrameBuffers(gpu, W, H)
    write_plane(buffers, DENOISED, image)
    tonemapping = TonemapPass(gpu, W, H, DENOISED, **settings)
    submit(gpu, [tonemapping], buffers)
    raw = gpu.device.queue.read_buffer(buffers.get(tonemapping.display))
    return tonemapping.image(raw, W, H)


def hdr_image(seed=2):
    return np.random.default_rng(seed).exponential(1.5, (H, W, 3)).astype(np.float32)


@pytest.mark.parametrize("operator", ["none", "reinhard", "aces"])
@pytest.mark.parametrize("exposure", [0.0, -1.5])
def test_tonemap_rgba8_matches_reference(gpu, operator, exposure):
    image = hdr_image()
    ours = tonemap_on_gpu(gpu, image, operator=operator, exposure=exposure)
    ref = tonemap(image, operator, exposure)
    assert ours.dtype == np.uint8 and ours.shape == (H, W, 4)
    assert np.abs(ours.astype(int) - ref.astype(int)).max() <= 1      # rounding at a .5 boundary
    assert np.mean(ours != ref) < 0.01
    assert np.all(ours[..., 3] == 255)


@pytest.mark.parametrize("operator", ["none", "reinhard", "aces"])
def test_tonemap_f32_matches_reference(gpu, operator):
    image = hdr_image(3)
    check_parity(None, lambda x: tonemap(x, operator, 0.5, output="f32"),
                 lambda x: tonemap_on_gpu(gpu, x, operator=operator, exposure=0.5, output="f32"),
                 atol=2e-6, rtol=2e-6, inputs=[image], name=f"tonemap {operator}")


def test_tonemap_linear_passthrough_keeps_hdr(gpu):
    image = hdr_image(4) * 1000
    out = tonemap_on_gpu(gpu, image, operator="none", srgb=False, output="f32")
    np.testing.assert_allclose(out[..., :3], image, rtol=1e-6)


def test_aces_reference_known_points():
    """Hill's fit maps 0 to ~0, scene mid grey 0.18 to about 10 % of display white (as the ACES SDR
    output transform does: 10 of 100 cd/m²) and saturates to white."""
    out = aces_fitted(np.array([[0.0] * 3, [0.18] * 3, [1e9] * 3]))
    assert out[0].max() < 2e-3 and 0.09 < out[1, 0] < 0.12 and np.allclose(out[2], 1.0)


def test_srgb_reference_known_points():
    out = tonemap(np.array([[[0.0, 0.0031308, 1.0]]], np.float32), "none", output="f32")
    np.testing.assert_allclose(out[0, 0, :3], [0.0, 0.04045, 1.0], atol=1e-5)


@pytest.mark.parametrize("operator", ["none", "reinhard", "aces"])
@pytest.mark.parametrize("poison", [np.nan, np.inf, -np.inf, 3.4e38])
def test_tonemap_never_emits_non_finite(gpu, operator, poison):
    rng = np.random.default_rng(5)
    image = hdr_image(5)
    image[rng.uniform(size=image.shape) < 0.2] = poison
    out = tonemap_on_gpu(gpu, image, operator=operator, output="f32")
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out, tonemap(image, operator, output="f32"), atol=2e-6, rtol=2e-6)


@pytest.mark.parametrize("operator", ["none", "reinhard", "aces"])
@pytest.mark.parametrize("exposure", [-MAX_EXPOSURE_STOPS, MAX_EXPOSURE_STOPS])
def test_tonemap_matches_reference_from_subnormal_to_float_max(gpu, operator, exposure):
    """Inputs from float32's smallest normals to its largest finite value, at the extreme exposures:
    products that over- or underflow, and (with the H100's flush to zero) subnormal intermediates.
    (rtol: WGSL's pow is exp2(y · log2 x), a few 1e-6 off for the sRGB curve of ~1e38.)"""
    image = np.logspace(-37.9, 38.5, H * W * 3).astype(np.float32)
    image[-1] = np.finfo(np.float32).max
    image = image.reshape(H, W, 3)
    out = tonemap_on_gpu(gpu, image, operator=operator, exposure=exposure, output="f32")
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out, tonemap(image, operator, exposure, output="f32"), atol=2e-6, rtol=1e-5)


def test_tonemap_divisors_stay_where_wgsl_divides_accurately():
    """WGSL promises x / y only for |y| ≤ 2^126, and NVIDIA multiplies by a reciprocal that flushes to
    zero beyond (Reinhard gave 0 for 3.4e38 there), which lavapipe does not show: the shader clamps
    Reinhard's input to a bound it shares with the reference, where the curve is already 1 in float32."""
    shader = read_wgsl("frame/tonemap.wgsl")
    bound = np.float32(re.search(r"const CURVE_INPUT_MAX: f32 = ([0-9.e+]+);", shader).group(1))
    assert bound == np.float32(CURVE_INPUT_MAX)
    assert np.float32(1) + bound <= 2.0 ** 126 and bound / (np.float32(1) + bound) == 1


@pytest.mark.parametrize("exposure", [MAX_EXPOSURE_STOPS + 0.5, -200, np.nan, np.inf, "2"])
def test_exposure_out_of_range_is_named(exposure):
    """Beyond ±126 stops 2^exposure is no normal float32 (0 or inf on the GPU, and 0·inf is NaN)."""
    with pytest.raises(WgpuRtError, match="exposure"):
        tonemap(hdr_image(), "aces", exposure)


def test_bad_operator_names_it():
    with pytest.raises(WgpuRtError, match="'filmic'"):
        tonemap(hdr_image(), "filmic")
