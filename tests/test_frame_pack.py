"""The packing passes against their numpy references (which training uses), and sanitising stress."""

import numpy as np
import pytest
from parity import check_parity

from wgpu_rt.frame.pack import (
    CONFIDENCE_KEY,
    EXPOSURE_KEY,
    EXPOSURE_LIMIT,
    NO_BALANCE,
    WHITE_BALANCE_FLOOR,
    DepthMaxPass,
    PackConfidencePass,
    PackDenoiserPass,
    PackErrorPass,
    RadianceExposurePass,
    WhiteBalancePass,
    exposure_scale,
    frame_exposure,
    frame_irradiance,
    pack_confidence_input,
    pack_denoiser_input,
    pack_error_input,
    probe_exposure,
    radiance_exposure,
    white_balance_gains,
)
from wgpu_rt.frame.planes import (
    CONFIDENCE_INPUT,
    DENOISER_INPUT,
    ERROR_INPUT,
    write_plane,
)
from wgpu_rt.passes import ALBEDO, DEPTH, NORMAL, RADIANCE, SPP, FrameBuffers, PlaneSpec

H, W = 21, 37   # not multiples of the 8×8 tile, so edge guards are exercised


def run(gpu, passes, planes, width=W, height=H):
    buffers = FrameBuffers(gpu, width, height)
    for spec, image in planes.items():
        write_plane(buffers, spec, image)
    encoder = gpu.device.create_command_encoder()
    for p in passes:
        p.execute(encoder, buffers)
    gpu.device.queue.submit([encoder.finish()])
    return buffers


def denoiser_on_gpu(gpu, color, albedo, normal, depth, spp=None):
    """The pack pass's output; ``spp`` None leaves the trace's sample-count plane at 0 (counts as 1)."""
    depth_max, balance = DepthMaxPass(gpu, W, H), WhiteBalancePass(gpu, W, H)
    planes = {RADIANCE: color, ALBEDO: albedo, NORMAL: normal, DEPTH: depth}
    if spp is not None:
        planes[SPP] = np.asarray(spp, np.uint32)
    buffers = run(gpu, [depth_max, balance, PackDenoiserPass(gpu, W, H, depth_max.result, balance.result)], planes)
    return buffers.read(DENOISER_INPUT.name)


def balance_on_gpu(gpu, color, albedo, balance=True, exposure=True):
    height, width = color.shape[:2]
    balance = WhiteBalancePass(gpu, width, height, balance, exposure)
    run(gpu, [balance], {RADIANCE: color, ALBEDO: albedo}, width, height)
    gains_and_exposure = gpu.read(balance.result, shape=(4,))
    assert gains_and_exposure[3] == pytest.approx(frame_exposure(color, albedo), rel=2e-5)
    return gains_and_exposure[:3]


def random_planes(rng):
    color = rng.exponential(2.0, (H, W, 3)).astype(np.float32)
    albedo = rng.uniform(0, 1, (H, W, 3)).astype(np.float32)
    normal = rng.normal(size=(H, W, 3)).astype(np.float32)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    depth = rng.uniform(0.5, 30, (H, W)).astype(np.float32)
    depth[rng.uniform(size=(H, W)) < 0.2] = 0.0          # misses
    return color, albedo, normal, depth


def test_pack_denoiser_matches_reference(gpu):
    rng = np.random.default_rng(1)
    spp = rng.integers(0, 5000, (H, W))                    # an adaptive map, with 0s (counted as 1)
    inputs = (*random_planes(rng), spp)
    out, ref = check_parity(None, pack_denoiser_input, lambda *a: denoiser_on_gpu(gpu, *a),
                            atol=1e-6, rtol=1e-6, inputs=inputs, name="pack_denoiser")
    assert ref.shape == (11, H, W)
    assert ref[9].max() == pytest.approx(1.0)              # depth normalised by the frame max
    np.testing.assert_allclose(ref[10], 1 / np.sqrt(np.maximum(spp, 1)), rtol=1e-6)


def test_pack_denoiser_reference_layout():
    """The reference itself, against values worked out by hand (so a wrong reference cannot pass)."""
    color = np.zeros((1, 2, 3), np.float32)
    color[0, 0] = [1.01 * (np.e - 1), -5, np.nan]
    color[0, 1] = [np.inf, 0, 1e-8]
    albedo = np.array([[[2.0, 2.0, 2.0], [np.nan, -1.0, 0.0]]], np.float32)   # factors 1 + 0.01, 0 + 0.01
    normal = np.array([[[0, 0, 1], [np.nan, -1, 0]]], np.float32)
    depth = np.array([[2.0, 8.0]], np.float32)
    x = pack_denoiser_input(color, albedo, normal, depth, balance=NO_BALANCE)
    np.testing.assert_allclose(x[:3, 0, 0], [1, 0, 0], atol=1e-6)      # colour / albedo factor
    np.testing.assert_allclose(x[:3, 0, 1], [0, 0, 1e-6], rtol=1e-5)
    np.testing.assert_array_equal(x[3:6, 0, 0], 1.0)
    np.testing.assert_array_equal(x[3:6, 0, 1], 0.0)
    np.testing.assert_allclose(x[6:9, 0, 0], [0.5, 0.5, 1.0])
    np.testing.assert_allclose(x[6:9, 0, 1], [0.5, 0.0, 0.5])
    np.testing.assert_allclose(x[9, 0], [0.25, 1.0])
    np.testing.assert_array_equal(x[10], 1.0)                         # one sample unless told
    balanced = pack_denoiser_input(color, albedo, normal, depth, balance=np.array([0.5, 1.0, 4.0], np.float32))
    np.testing.assert_allclose(balanced[:3, 0, 0], [np.log1p((np.e - 1) * 2), 0, 0], atol=1e-6)   # ÷ factor·gain
    np.testing.assert_allclose(balanced[:3, 0, 1], [0, 0, 0.25e-6], rtol=1e-5)
    np.testing.assert_array_equal(pack_denoiser_input(color, albedo, normal, depth, 16)[10], 0.25)
    np.testing.assert_array_equal(pack_denoiser_input(color, albedo, normal, depth, [[4, 0]])[10], [[0.5, 1]])


def test_pack_denoiser_no_hit_frame_packs_zero_depth(gpu):
    color, albedo, normal, _ = random_planes(np.random.default_rng(2))
    out = denoiser_on_gpu(gpu, color, albedo, normal, np.zeros((H, W), np.float32))
    assert np.all(out[9] == 0)


@pytest.mark.parametrize("poison", [np.nan, np.inf, -np.inf, -1e30, 3e38])
def test_pack_denoiser_never_emits_non_finite(gpu, poison):
    rng = np.random.default_rng(3)
    planes = list(random_planes(rng))
    for plane in planes:
        plane[rng.uniform(size=plane.shape) < 0.1] = poison
    out = denoiser_on_gpu(gpu, *planes)
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out, pack_denoiser_input(*planes), atol=1e-6, rtol=1e-6)
    assert out.min() >= 0 and out[3:].max() <= 1.0


def test_pack_keeps_fp16_range(gpu):
    """Radiance up to f16's max over black albedo (÷ 0.01) lands near 15.7 in log space, representable
    in half precision."""
    color = np.full((H, W, 3), 65504.0, np.float32)
    color[::2] = np.float32(1e-3)
    _, albedo, normal, depth = random_planes(np.random.default_rng(4))
    albedo[1, 1] = 0.0
    out = denoiser_on_gpu(gpu, color, albedo, normal, depth)
    np.testing.assert_allclose(out, pack_denoiser_input(color, albedo, normal, depth), rtol=1e-6, atol=1e-6)
    assert out[:3].max() <= np.log1p(65504.0 / 0.01 / WHITE_BALANCE_FLOOR) < 65504.0
    assert np.all(np.isfinite(out.astype(np.float16)))


def test_white_balance_reference_by_hand():
    """The gains are the square roots of the irradiance's channel means over their mean, at least the
    floor; a black frame is left alone; scaling the frame changes nothing."""
    albedo = np.full((2, 2, 3), 0.99, np.float32)                  # factor 1
    color = np.zeros((2, 2, 3), np.float32)
    color[0, 0] = [16.0, 4.0, 0.0]                                 # means 4, 1, 0: roots 2, 1, 0; their mean 1

    def gains(c):
        return white_balance_gains(c, albedo, exposure=False)

    np.testing.assert_allclose(gains(color), [2.0, 1.0, WHITE_BALANCE_FLOOR], rtol=1e-6)
    np.testing.assert_array_equal(gains(np.zeros_like(color)), [1.0, 1.0, 1.0])
    np.testing.assert_allclose(gains(1e-6 * color), gains(color), rtol=1e-6)
    color[1, 1] = [np.nan, -3.0, np.inf]                           # sanitised away
    np.testing.assert_allclose(gains(color), [2.0, 1.0, WHITE_BALANCE_FLOOR], rtol=1e-6)
    np.testing.assert_array_equal(white_balance_gains(color, albedo, balance=False, exposure=False), NO_BALANCE)


def test_exposure_reference_by_hand():
    """The key is the log-average of the 8×8 tiles' mean luminance (tiles cut short at the frame's edges,
    black tiles left out), brought to EXPOSURE_KEY: the gains then scale with the frame's light, so that the
    irradiance the network reads does not."""
    irradiance = np.zeros((3, 9, 16))
    irradiance[:, :8, :8] = 0.3 * 4.0                              # tile means 1.2, 0.3 / 4, a dark corner strip
    irradiance[:, :8, 8:] = 0.3 / 4.0                              # and a black strip below: key 0.3
    irradiance[0, 8, :8] = 1e-9                                    # a tile of 8 pixels at 1e-9 / 3: left out
    assert exposure_scale(irradiance) == pytest.approx(1.0, rel=1e-12)
    irradiance[:, 8, 8:] = 0.3 * 1e-3                              # a third tile, of 8 pixels
    assert exposure_scale(irradiance) == pytest.approx(1e-3 ** (1 / 3), rel=1e-9)
    assert exposure_scale(np.zeros((3, 5, 5))) == 1.0              # nothing lit: left alone
    assert exposure_scale(np.full((3, 2, 2), 1e30)) == EXPOSURE_LIMIT
    color = np.random.default_rng(0).exponential(1.0, (19, 23, 3)).astype(np.float32)
    albedo = np.full_like(color, 0.5)
    for stops in (-20, -6, 0, 5):
        np.testing.assert_allclose(white_balance_gains(2.0 ** stops * color, albedo),
                                   2.0 ** stops * white_balance_gains(color, albedo), rtol=1e-5)
    key = exposure_scale(frame_irradiance(color, albedo)) * EXPOSURE_KEY
    np.testing.assert_allclose(white_balance_gains(color, albedo, balance=False), NO_BALANCE * key / EXPOSURE_KEY,
                               rtol=1e-6)


@pytest.mark.parametrize("balance, exposure", [(True, True), (True, False), (False, True)])
@pytest.mark.parametrize("size", [(21, 37), (157, 203)])   # one tile row; more tiles than the reduction's 256 lanes
def test_white_balance_pass_matches_reference(gpu, size, balance, exposure):
    rng = np.random.default_rng(7)
    color = (rng.exponential(1.0, size + (3,)) * [0.2, 1.5, 0.6]).astype(np.float32)   # a green cast
    albedo = rng.uniform(-0.1, 1.1, size + (3,)).astype(np.float32)
    color[rng.uniform(size=color.shape) < 0.01] = np.inf
    color[:5, :9] *= 1e-12                                         # a dark corner moves the key, not the mean

    def reference(c, a):
        return white_balance_gains(c, a, balance, exposure)

    def ours(c, a):
        return balance_on_gpu(gpu, c, a, balance, exposure)

    _, gains = check_parity(None, reference, ours, atol=0.0, rtol=2e-5, inputs=[color, albedo], name="white balance")
    assert (gains[1] > 1.2 * gains[0]) == balance                  # the cast is seen
    np.testing.assert_array_equal(ours(np.zeros_like(color), albedo), [1.0, 1.0, 1.0])
    color[0, 0, 1], albedo[0, 0] = 3e38, 0.0                       # green irradiance past f32's range
    check_parity(None, reference, ours, atol=0.0, rtol=2e-5, inputs=[color, albedo],
                 name="white_balance_gains, clamped irradiance")


def test_pack_error_matches_reference(gpu):
    color = np.random.default_rng(5).exponential(1.0, (H, W, 3)).astype(np.float32)
    color[0, 0] = np.nan

    def ours(c):
        return run(gpu, [PackErrorPass(gpu, W, H)], {RADIANCE: c}).read(ERROR_INPUT.name)

    check_parity(None, pack_error_input, ours, atol=1e-6, rtol=1e-6, inputs=[color], name="pack_error")


@pytest.mark.parametrize("size", [(21, 37), (157, 203)])   # one tile row; more tiles than the reduction's 256 lanes
def test_probe_exposure_pass_matches_reference(gpu, size):
    """The error predictor's probe brought to PROBE_KEY: the radiance's own key (no albedo), found on the
    device, then the packing divides by it; a probe at any scale packs alike."""
    rng = np.random.default_rng(8)
    color = rng.exponential(0.05, size + (3,)).astype(np.float32)
    color[rng.uniform(size=color.shape) < 0.01] = np.inf
    color[:5, :9] *= 1e-12                                         # a dark corner moves the key
    color[1, 1] = [3e38, np.nan, -1.0]

    def ours(c):
        exposure = RadianceExposurePass(gpu, size[1], size[0])
        packing = PackErrorPass(gpu, size[1], size[0], exposure.result)
        buffers = run(gpu, [exposure, packing], {RADIANCE: c}, size[1], size[0])
        gains_and_scale = gpu.read(exposure.result, shape=(4,))
        np.testing.assert_allclose(gains_and_scale, probe_exposure(c), rtol=2e-5)
        return buffers.read(ERROR_INPUT.name)

    def reference(c):
        return pack_error_input(c, probe_exposure(c))

    check_parity(None, reference, ours, atol=1e-5, rtol=2e-5, inputs=[color], name="probe exposure")
    color[1, 1] = 0.0                                               # past f32's range when scaled up
    for stops in (-20, -5, 7):                                      # tiles stay above KEY_FLOOR
        np.testing.assert_allclose(reference(np.float32(2.0 ** stops) * color), reference(color), rtol=1e-5,
                                   atol=1e-6)
    np.testing.assert_array_equal(pack_error_input(color, 1.0), pack_error_input(color))
    assert probe_exposure(np.zeros_like(color)) == 1.0              # nothing lit: read as it is


def test_pack_confidence_matches_reference(gpu):
    rng = np.random.default_rng(6)
    color, _, _, depth = random_planes(rng)
    history = rng.exponential(2.0, (H, W, 3)).astype(np.float32)
    previous_depth = rng.uniform(0, 40, (H, W)).astype(np.float32)
    history[1, 1] = np.inf
    current = PlaneSpec("current", 3)
    reprojected = PlaneSpec("reprojected", 5)   # frame/temporal.wgsl: RGB, previous depth, history length

    def ours(c, h, d, pd, key=None):
        depth_max = DepthMaxPass(gpu, W, H)
        exposure = RadianceExposurePass(gpu, W, H, key, current) if key else None
        packing = PackConfidencePass(gpu, W, H, current, reprojected, depth_max.result,
                                     exposure.result if exposure else None)
        reprojected_planes = np.concatenate([h, pd[..., None], np.ones_like(pd)[..., None]], axis=-1)
        return run(gpu, [depth_max, *([exposure] if exposure else []), packing],
                   {current: c, reprojected: reprojected_planes, DEPTH: d}).read(CONFIDENCE_INPUT.name)

    planes = [color, history, depth, previous_depth]
    check_parity(None, pack_confidence_input, ours, atol=1e-6, rtol=1e-6, inputs=planes, name="pack_confidence")
    for key in (CONFIDENCE_KEY, 3.0):                                # the frame and its history at one key
        def reference(c, h, d, pd):
            return pack_confidence_input(c, h, d, pd, radiance_exposure(c, key))

        _, packed = check_parity(None, reference, lambda *p: ours(*p, key=key), atol=1e-5, rtol=2e-5,
                                 inputs=planes, name=f"pack_confidence at key {key}")
        assert packed[:6].mean() != pytest.approx(pack_confidence_input(*planes)[:6].mean(), rel=0.05)


def test_frame_kernels_take_binding_indices_from_the_wgsl(gpu):
    """A pass names the bindings an entry point uses; their indices come from the shader's declarations
    (declared once), and a name the shader does not declare is caught at construction."""
    from wgpu_rt.frame.kernel import FrameKernel

    kernel = FrameKernel(gpu, "frame/pack.wgsl", "pack_error", ("packed", "color"), W, H)
    assert kernel.bindings == ["color", None, None, None, None, None, "packed"]
    with pytest.raises(ValueError, match="colour"):
        FrameKernel(gpu, "frame/pack.wgsl", "pack_error", ("colour", "packed"), W, H)
