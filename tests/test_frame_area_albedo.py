"""The tracer's point-sampled albedo smoothed for the denoiser (frame/area_albedo.py): the device pass
against its numpy reference at sizes that are not multiples of the 8×8 tile, with a per-pixel sample map
and poisoned values; a uniform map as the one-count path; the frame pipeline without the aux pass."""

import numpy as np
import pytest
from parity import check_parity, run_frame_pass

from wgpu_rt.frame.area_albedo import POINT_ALBEDO, AreaAlbedoPass, area_averaged_albedo
from wgpu_rt.passes import ALBEDO, SPP
from wgpu_rt.renderer import render


def smoothed_on_gpu(gpu, width, height, albedo, counts):
    area = AreaAlbedoPass(gpu, width, height)
    buffers = run_frame_pass(gpu, area, width, height, {ALBEDO: albedo, SPP: counts})
    smoothed = gpu.read(buffers.get(ALBEDO), np.float32, (3, height, width)).transpose(1, 2, 0)
    kept = gpu.read(buffers.get(POINT_ALBEDO), np.float32, (3, height, width)).transpose(1, 2, 0)
    encoder = gpu.device.create_command_encoder()
    area.restore(encoder, buffers)
    gpu.device.queue.submit([encoder.finish()])
    restored = gpu.read(buffers.get(ALBEDO), np.float32, (3, height, width)).transpose(1, 2, 0)
    return smoothed, kept, restored


@pytest.mark.parametrize("width,height", [(21, 13), (9, 30), (1, 1), (40, 37)])
def test_the_device_pass_matches_the_reference_and_restores_the_tracers_albedo(gpu, width, height):
    rng = np.random.default_rng(width * height)
    albedo = rng.uniform(0, 1, (height, width, 3)).astype(np.float32)
    albedo[rng.uniform(size=(height, width)) < 0.05] = np.nan   # a failed sample counts as 0
    counts = rng.choice([0, 1, 2, 3, 4, 16, 100, 1000], (height, width)).astype(np.uint32)
    smoothed, kept, restored = smoothed_on_gpu(gpu, width, height, albedo, counts)
    check_parity(None, lambda a: area_averaged_albedo(a, counts), lambda a: smoothed, atol=1e-5,
                 inputs=[albedo], name="area albedo")
    np.testing.assert_array_equal(kept, albedo)
    np.testing.assert_array_equal(restored, albedo)


def test_a_uniform_map_smooths_as_one_count():
    rng = np.random.default_rng(1)
    albedo = rng.uniform(0, 1, (11, 17, 3)).astype(np.float32)
    for samples in (1, 2, 4, 9):
        np.testing.assert_allclose(area_averaged_albedo(albedo, np.full((11, 17, 1), samples)),
                                   area_averaged_albedo(albedo, samples), rtol=1e-6, atol=1e-7)
    np.testing.assert_array_equal(area_averaged_albedo(albedo, np.zeros((11, 17))), albedo)   # an aux-pass albedo


def test_a_frame_without_the_aux_pass_denoises_its_albedo_smoothed(gpu):
    """Without the aux pass a denoised frame equals ``denoise()`` on its traced planes with the albedo
    smoothed by each pixel's samples, while the albedo it reads back stays the tracer's; under a static
    view (temporal mode) the samples keep accumulating into the tracer's albedo, not into a smoothed one."""
    from wgpu_rt.frame.denoise import denoise, load_model

    model = load_model("denoiser", ctx=gpu)
    options = dict(spp=1, size=(37, 29), seed=4, ctx=gpu)   # (above 1 spp the frame hands over to the mean)
    planes = render("cornell", aovs=("albedo", "normal", "depth", "spp"), aux_samples=0, **options)
    frame = render("cornell", denoise=True, aux_samples=0, aovs=("albedo",), networks={"denoiser": model}, **options)
    smoothed = area_averaged_albedo(planes.aovs["albedo"], planes.aovs["spp"])
    expected = denoise(model, planes.color, smoothed, planes.aovs["normal"], planes.aovs["depth"], planes.aovs["spp"])
    np.testing.assert_allclose(frame.color, expected, rtol=1e-4, atol=1e-5)
    np.testing.assert_array_equal(frame.aovs["albedo"], planes.aovs["albedo"])
    unsmoothed = denoise(model, planes.color, *(planes.aovs[name] for name in ("albedo", "normal", "depth", "spp")))
    assert not np.allclose(frame.color, unsmoothed, rtol=1e-3, atol=1e-4)

    static = dict(aux_samples=0, aovs=("albedo",), temporal=True, frames=range(3), **options)
    plain = render("cornell", **static)
    denoised = render("cornell", denoise=True, networks={"denoiser": model}, **static)
    for traced, kept in zip(plain, denoised):
        np.testing.assert_allclose(kept.aovs["albedo"], traced.aovs["albedo"], rtol=1e-6, atol=1e-7)
