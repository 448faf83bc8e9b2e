"""A frame whose packed denoiser input is wider than one storage binding (past about 2560×1440 on lavapipe's
128 MiB) is denoised in bands of rows (frame/bands.py: the network's, and the post filter's taller ones) and keeps
what the whole frame gives. The device's binding limit is shrunk to force that at a small size."""

import numpy as np
import pytest

from wgpu_rt.errors import DeviceLimitError
from wgpu_rt.frame.bands import plan_bands
from wgpu_rt.frame.planes import DENOISER_INPUT

W, H = 48, 800


def test_bands_cover_the_frame_with_context_either_side_on_the_pooling_grid():
    bands = plan_bands(1000, 300, 64, 16)
    assert bands[0].top == bands[0].start == 0 and bands[-1].stop == bands[-1].bottom == 1000
    assert all(before.stop == after.start for before, after in zip(bands, bands[1:]))
    for band in bands:
        assert band.rows <= 288 and band.top % 16 == 0 and band.start < band.stop
        assert band.top == 0 or band.start - band.top >= 64
        assert band.bottom == 1000 or band.bottom - band.stop >= 64
    assert [band.rows for band in bands[:-1]] == [288] * (len(bands) - 1)
    assert plan_bands(200, 300, 64, 16) == plan_bands(200, 10_000, 64, 16)   # one band: the whole frame
    with pytest.raises(DeviceLimitError, match="too wide for this device"):
        plan_bands(1000, 140, 64, 16)


@pytest.fixture
def narrow(gpu):
    """The same device, as if one storage binding held about 320 rows of a W-pixel frame's network activations
    (fewer than the frame's packed input needs)."""
    from wgpu_rt.gpu import GpuContext

    narrow = GpuContext(gpu.adapter, gpu.device, gpu.features)
    narrow.__dict__["limits"] = {**gpu.limits, "max-storage-buffer-binding-size": 320 * 64 * W * 100 // 95}
    assert DENOISER_INPUT.nbytes(W, H) > narrow.limits["max-storage-buffer-binding-size"]
    return narrow


def test_denoise_in_bands_equals_the_whole_frame(gpu, narrow):
    """``denoise()`` with every step on (low band, chroma hold, post filter, the hand-over to the samples' mean)
    gives, in bands, what it gives on the whole frame: noisy colour on one flat surface, which the network reads
    and the post filter smooths far, so that any band edge read without its context shows."""
    from wgpu_rt.frame.denoise import DenoiseOnDevice, denoise, load_model

    rng = np.random.default_rng(5)
    color = rng.gamma(0.5, 2.0, (H, W, 3)).astype(np.float32)
    layers = [np.full((H, W, 3), 0.5), np.broadcast_to([0.0, 0.0, 1.0], (H, W, 3)), np.full((H, W, 1), 2.0)]
    spp = rng.integers(2, 9, (H, W, 1))
    half = (color * rng.uniform(0.5, 1.5, (H, W, 3)).astype(np.float32), spp[..., 0] // 2)
    denoised = {}
    for name, ctx in (("whole", gpu), ("bands", narrow)):
        model = load_model("denoiser", "fp32", ctx=ctx)
        denoised[name] = denoise(model, color, *layers, spp, low_band=True, half=half)
        chains = [made.chain for made in DenoiseOnDevice._made[model].values()]
        assert [chain.bands is not None for chain in chains] == [name == "bands"]
        assert name == "whole" or (len(chains[0].bands.bands) > 2 and len(chains[0].bands.filter_bands) > 1
                                   and chains[0].low_band is not None)
    np.testing.assert_allclose(denoised["bands"], denoised["whole"], rtol=1e-5, atol=1e-6)


def test_a_rendered_frame_in_bands_equals_the_whole_frame(gpu, narrow):
    """The frame loop wires the chain in bands (its stages check) and shows the same frame."""
    from wgpu_rt.frame.denoise import load_model
    from wgpu_rt.renderer import Renderer

    frames = {}
    for name, ctx in (("whole", gpu), ("bands", narrow)):
        renderer = Renderer("cornell", 2, (W, H), ctx=ctx, seed=9, denoise=True, aovs=(), low_band=True,
                            networks={"denoiser": load_model("denoiser", "fp32", ctx=ctx)})
        assert (renderer.pipeline.chain.bands is not None) == (name == "bands")
        frames[name] = next(iter(renderer.frames(None))).color
    np.testing.assert_allclose(frames["bands"], frames["whole"], rtol=1e-5, atol=1e-6)
