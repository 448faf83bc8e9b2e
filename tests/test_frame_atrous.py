"""The edge-aware à-trous filter after the denoiser (frame/atrous.py): the device pass against its numpy
reference at sizes that are not multiples of the 8×8 tile (and smaller than the filter's reach),
poisoned inputs, the reference against hand-worked cases, and the flag."""

import numpy as np
import pytest
from parity import check_parity, run_frame_pass

from wgpu_rt.frame.atrous import FILTER_LIMIT, AtrousPass, atrous_filter
from wgpu_rt.frame.pack import AS_TUNED
from wgpu_rt.frame.planes import DENOISED
from wgpu_rt.passes import ALBEDO, DEPTH, NORMAL, SPP

SIZES = [(21, 13), (24, 16), (9, 30), (1, 1), (40, 37)]   # (W, H)


def atrous_on_gpu(gpu, width, height, denoised, albedo, normal, depth, spp=None, exposure=None):
    planes = {DENOISED: denoised, ALBEDO: albedo, NORMAL: normal, DEPTH: depth,
              SPP: np.ones((height, width), np.uint32) if spp is None else spp}
    scale = None if exposure is None else gpu.upload(np.array([1, 1, 1, exposure], np.float32), label="exposure")
    buffers = run_frame_pass(gpu, AtrousPass(gpu, width, height, scale), width, height, planes)
    return gpu.read(buffers.get(DENOISED), np.float32, (3, height, width)).transpose(1, 2, 0)


def noisy_scene(rng, width, height):
    """Two surfaces (left and right half: different albedo, normal and depth), radiance on both with
    a residue of ±5 %, the scale the filter is for."""
    left = np.arange(width)[None, :, None] < width // 2
    albedo = np.where(left, [0.8, 0.2, 0.2], [0.3, 0.6, 0.9]).astype(np.float32) * np.ones((height, 1, 1), np.float32)
    normal = np.where(left, [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]).astype(np.float32) * np.ones((height, 1, 1), np.float32)
    depth = np.where(left[..., 0], 2.0, 3.0).astype(np.float32) * np.ones((height, 1), np.float32)
    radiance = (albedo * rng.uniform(0.95, 1.05, (height, width, 1))).astype(np.float32)
    return radiance, albedo, normal, depth


@pytest.mark.parametrize("width,height", SIZES)
def test_atrous_matches_reference(gpu, width, height):
    rng = np.random.default_rng(width * 13 + height)
    inputs = list(noisy_scene(rng, width, height))
    inputs[2] = inputs[2] + rng.normal(0, 0.05, inputs[2].shape).astype(np.float32)   # unlike normals too
    inputs.append(rng.choice([0, 1, 16, 64, 1024], (height, width)).astype(np.uint32))   # the tolerance fades
    check_parity(None, atrous_filter, lambda *a: atrous_on_gpu(gpu, width, height, *a),
                 atol=1e-5, rtol=1e-5, inputs=inputs, name=f"atrous {width}x{height}")


def test_atrous_reads_the_frame_at_one_key(gpu):
    """The luminance is read at the frame's exposure brought to pack.STEPS_KEY: a frame scaled by 2^8 with
    its exposure scaled alike is filtered as the frame is (on the device as by the reference); read as it is
    (the default, AS_TUNED) the bright frame saturates the display and is smoothed across its edges."""
    rng = np.random.default_rng(5)
    inputs = list(noisy_scene(rng, 24, 16))
    shadow = np.where(np.arange(24)[None, :, None] < 6, 0.25, 1.0).astype(np.float32)   # on one surface
    inputs[0] = inputs[0] * shadow
    filtered = atrous_filter(*inputs)
    scale = np.float32(2.0 ** 8)
    bright = [inputs[0] * scale, *inputs[1:], np.ones((16, 24), np.uint32), AS_TUNED * scale]
    check_parity(None, atrous_filter, lambda *a: atrous_on_gpu(gpu, 24, 16, *a), atol=1e-5, rtol=1e-5,
                 inputs=bright, name="atrous, a bright frame's exposure")
    np.testing.assert_allclose(atrous_filter(*bright) / scale, filtered, rtol=1e-4, atol=1e-7)
    as_given = atrous_filter(inputs[0] * scale, *inputs[1:]) / scale
    assert np.abs(as_given - filtered).max() > 0.05 * filtered.max()


@pytest.mark.parametrize("poison", [np.nan, np.inf, -np.inf, -1.0, np.finfo(np.float32).max])
def test_atrous_never_emits_non_finite(gpu, poison):
    rng = np.random.default_rng(4)
    planes = noisy_scene(rng, 21, 13)
    for plane in planes:
        plane[rng.uniform(size=plane.shape) < 0.15] = poison
    out = atrous_on_gpu(gpu, 21, 13, *planes)
    assert np.all(np.isfinite(out)) and out.min() >= 0 and out.max() <= FILTER_LIMIT * (1 + 1e-6)
    np.testing.assert_allclose(out, atrous_filter(*planes), rtol=1e-5, atol=1e-6)


def test_atrous_by_hand():
    rng = np.random.default_rng(5)
    radiance, albedo, normal, depth = noisy_scene(rng, 32, 24)
    # a flat frame stays as it is
    flat = np.full_like(radiance, 0.7)
    np.testing.assert_allclose(atrous_filter(flat, albedo, normal, depth), flat, rtol=1e-6)
    # noise within a surface falls; nothing crosses the edge between the two surfaces
    out = atrous_filter(radiance, albedo, normal, depth)
    for half in (slice(0, 16), slice(16, 32)):
        ratio_in, ratio_out = radiance[:, half] / albedo[:, half], out[:, half] / albedo[:, half]
        assert ratio_out.std() < 0.5 * ratio_in.std()
        np.testing.assert_allclose(ratio_out.mean(), ratio_in.mean(), rtol=0.01)   # each keeps its level
    assert np.abs(out[:, 15] / albedo[:, 15] - 1).max() < 0.05 and np.abs(out[:, 16] / albedo[:, 16] - 1).max() < 0.05
    # the tolerance narrows past FADE_SPP samples: at 1024 spp the same residue is left nearly as it is
    many = atrous_filter(radiance, albedo, normal, depth, 1024)
    assert np.abs(many - radiance).mean() < 0.3 * np.abs(out - radiance).mean()
    # a sharp brightness step on one surface (a shadow edge: same albedo, normal and depth) is kept
    step = np.where(np.arange(32)[None, :, None] < 16, 0.05, 2.0).astype(np.float32) * np.ones((24, 1, 3), np.float32)
    same = np.full((24, 32, 3), 0.5, np.float32)
    kept = atrous_filter(step, same, same, np.ones((24, 32), np.float32))
    np.testing.assert_allclose(kept, step, rtol=1e-3)


def test_post_filter_flag_needs_the_denoiser(tmp_path):
    from wgpu_rt.cli import main

    assert main(["render", "cornell", "--size", "8x8", "--spp", "1", "--post-filter", "off",
                 "--out", str(tmp_path / "x.exr")]) == 2
    assert not (tmp_path / "x.exr").exists()
