"""Adaptive sample counts against numpy references: the heat power map, exact budgets, the uniform and
variance (half-buffer) baselines; and the adaptive frame's samples against brute-force renders."""

import numpy as np
import pytest
from parity import check_parity, run_frame_pass

from wgpu_rt.errors import WgpuRtError
from wgpu_rt.frame.adaptive import (
    EXTRA_SAMPLES,
    HALF_RADIANCE,
    HEAT,
    MAX_HEAT_SAMPLES,
    SAMPLE_ERROR,
    AdaptiveSettings,
    ExtraSamplesPass,
    HalfBufferErrorPass,
    budget_weights,
    extra_samples_from_heat,
    half_buffer_error,
    ideal_budget_samples,
)
from wgpu_rt.frame.planes import write_plane
from wgpu_rt.passes import RADIANCE, SPP, FrameBuffers

H, W = 30, 44


def extra_on_gpu(gpu, importance, settings, source=HEAT):
    buffers = FrameBuffers(gpu, W, H)
    write_plane(buffers, source, importance)
    encoder = gpu.device.create_command_encoder()
    ExtraSamplesPass(gpu, W, H, settings, source).execute(encoder, buffers)
    gpu.device.queue.submit([encoder.finish()])
    return buffers.read(EXTRA_SAMPLES.name)[0]


def heatmap(seed=0):
    rng = np.random.default_rng(seed)
    heat = rng.uniform(0, 1, (H, W)).astype(np.float32)
    heat[5:12, 10:30] = rng.uniform(0.8, 1.0, (7, 20))
    return heat


@pytest.mark.parametrize("k", [1.0, 3.0])
def test_extra_from_heat_matches_reference(gpu, k):
    heat = heatmap()
    heat[0, :4] = [np.nan, np.inf, -1.0, 2.0]
    ours = extra_on_gpu(gpu, heat, AdaptiveSettings(k=k))
    ref = extra_samples_from_heat(heat, k)
    # floor() may land one lower/higher where heat^k·31 is within rounding of an integer
    assert np.abs(ours.astype(int) - ref.astype(int)).max() <= 1 and np.mean(ours != ref) < 0.01
    assert ours[0, :4].tolist() == [0, 0, 0, 31]


@pytest.mark.parametrize("budget", [1.0, 2.5, 4.0, 7.37])
@pytest.mark.parametrize("sampler, uniform_share", [("heat", 0.0), ("heat", 0.4), ("uniform", None)])
def test_budget_is_met_exactly(gpu, budget, sampler, uniform_share):
    heat = heatmap(1)
    settings = AdaptiveSettings(sampler=sampler, budget=budget, k=2.0, uniform_share=uniform_share)
    ours = extra_on_gpu(gpu, heat, settings)
    total = settings.extra_total(H * W)
    assert int(ours.sum(dtype=np.int64)) == total
    assert ours.max() <= settings.cap
    ideal = ideal_budget_samples(heat, total, 2.0, settings.evenly_spread, settings.pooling)
    if ideal.max() < settings.cap:
        assert np.abs(ours - ideal).max() < 1.0 + 1e-3


def test_uniform_share_is_every_pixels_floor(gpu):
    """With half the extra samples spread evenly, a pixel of zero heat still gets half the mean extra
    (rounded down), and the hot pixels share the rest."""
    heat = np.zeros((H, W), np.float32)
    heat[:, : W // 4] = 1.0
    settings = AdaptiveSettings(budget=5.0, uniform_share=0.5, pool_sigma=0.0)
    ours = extra_on_gpu(gpu, heat, settings)
    assert int(ours.sum()) == settings.extra_total(H * W)
    assert ours[:, W // 4:].min() == 2 and ours[:, : W // 4].min() >= 2 + 8


def test_budget_with_capped_pixels_still_exact(gpu):
    """A concentrated heatmap saturates a few pixels; what they cannot take goes to the others."""
    heat = np.zeros((H, W), np.float32)
    heat[:2, :2] = 1.0
    heat[10, 10] = 0.5
    settings = AdaptiveSettings(budget=3.0, k=1.0, cap=8)
    ours = extra_on_gpu(gpu, heat, settings)
    assert int(ours.sum()) == settings.extra_total(H * W)
    assert ours.max() == 8 and np.all(ours[:2, :2] == 8)


def test_pooled_weights_match_a_normalised_convolution():
    """budget_weights' pooling is the Gaussian-weighted mean over the taps inside the frame: scipy's
    zero-padded convolution of p² divided by that of an all-ones frame, computed independently."""
    from scipy.ndimage import convolve

    heat = heatmap(5).astype(np.float64)
    sigma, radius = 1.5, 3
    offsets = np.arange(-radius, radius + 1)
    kernel = np.exp(-(offsets[:, None] ** 2 + offsets[None, :] ** 2) / (2 * sigma ** 2))
    squared = heat ** 4
    pooled = convolve(squared, kernel, mode="constant") / convolve(np.ones_like(heat), kernel, mode="constant")
    np.testing.assert_allclose(budget_weights(heat, 2.0, sigma), np.sqrt(squared + pooled), rtol=1e-9)
    np.testing.assert_allclose(budget_weights(heat, 2.0, 0.0), heat ** 2, rtol=1e-12)


@pytest.mark.parametrize("pool_sigma", [0.6, 2.0])
def test_pooled_budget_map_matches_reference(gpu, pool_sigma):
    """The device's pooled weights give the reference's ideal shares within rounding (1 sample), and a
    lone hot pixel lends its neighbours samples that unpooled weights would not give them."""
    heat = heatmap(6)
    heat[20, 30] = 1.0
    heat[17:24, 27:34] *= 0.1
    heat[20, 30] = 1.0
    settings = AdaptiveSettings(budget=4.0, uniform_share=0.0, pool_sigma=pool_sigma)
    ours = extra_on_gpu(gpu, heat, settings)
    total = settings.extra_total(H * W)
    assert int(ours.sum()) == total
    ideal = ideal_budget_samples(heat, total, 2.0, 0.0, pool_sigma)
    assert np.abs(ours - ideal).max() < 1.0 + 1e-3
    unpooled = ideal_budget_samples(heat, total, 2.0, 0.0, 0.0)
    assert ideal[20, 31] > 2 * unpooled[20, 31]


def test_budget_ignores_non_finite_heat(gpu):
    heat = heatmap(2)
    heat[::3, ::5] = np.nan
    heat[1, 1] = np.inf
    settings = AdaptiveSettings(budget=3.0, uniform_share=0.0, pool_sigma=0.0)
    ours = extra_on_gpu(gpu, heat, settings)
    assert int(ours.sum()) == settings.extra_total(H * W)
    assert ours[::3, ::5].max() <= 1           # a NaN pixel weighs 0 (it may get a remainder sample)
    pooled = AdaptiveSettings(budget=3.0)      # pooled, a NaN pixel borrows only its neighbours' weight
    ours = extra_on_gpu(gpu, heat, pooled)
    assert int(ours.sum()) == pooled.extra_total(H * W) and ours.max() <= pooled.cap


def test_budget_map_is_deterministic(gpu):
    """The remainder is handed out by rank, not by whichever invocation wins an atomic: repeated runs on
    fresh buffers give the same map bit for bit, with and without capped pixels."""
    heat = heatmap(4)
    for settings in (AdaptiveSettings(budget=2.37, k=2.0), AdaptiveSettings(budget=3.0, k=1.0, cap=2)):
        runs = [extra_on_gpu(gpu, heat, settings) for _ in range(4)]
        assert int(runs[0].sum()) == settings.extra_total(H * W)
        for run in runs[1:]:
            np.testing.assert_array_equal(run, runs[0])


def scan_ranks(height, width, tile=8):
    """Each pixel's position in the remainder rounds' scan order: 8×8 tiles row-major, row-major inside."""
    y, x = np.mgrid[:height, :width]
    tiles_x = -(-width // tile)
    order = ((y // tile) * tiles_x + x // tile) * tile * tile + (y % tile) * tile + x % tile
    return np.argsort(np.argsort(order.ravel())).reshape(height, width)


def test_uniform_remainder_is_spread_by_rank(gpu):
    """Uniform budget 1 + 1.3: every pixel's ideal share is 0.3, so q = 0.3·N of the N equal claims win a
    sample; the winners are exactly the ranks r with (r·q mod N) + q ≥ N (evenly spread), reproduced in
    numpy from the scan order alone."""
    settings = AdaptiveSettings(sampler="uniform", budget=1.3)
    quota = settings.extra_total(H * W)
    ranks = scan_ranks(H, W).astype(np.int64)
    expected = ((ranks * quota) % (H * W) + quota >= H * W).astype(np.uint32)
    ours = extra_on_gpu(gpu, np.zeros((H, W), np.float32), settings)
    np.testing.assert_array_equal(ours, expected)
    top, bottom = ours[: H // 2].mean(), ours[H // 2:].mean()
    assert abs(top - bottom) < 0.05, (top, bottom)


def test_half_buffer_error_matches_reference(gpu):
    rng = np.random.default_rng(3)
    full = rng.exponential(1.0, (H, W, 3)).astype(np.float32)
    half = (full + rng.normal(0, 0.3, (H, W, 3))).astype(np.float32)
    half[0, 0] = np.nan

    def ours(f, h):
        buffers = run_frame_pass(gpu, HalfBufferErrorPass(gpu, W, H), W, H, {RADIANCE: f, HALF_RADIANCE: h})
        return buffers.read(SAMPLE_ERROR.name)[0]

    check_parity(None, half_buffer_error, ours, atol=1e-5, rtol=1e-5, inputs=[full, half],
                 name="half-buffer error")


def test_variance_sampler_follows_the_error(gpu):
    error = np.full((H, W), 0.01, np.float32)
    error[:, : W // 4] = 1.0
    settings = AdaptiveSettings(sampler="variance", budget=4.0, uniform_share=0.0)
    ours = extra_on_gpu(gpu, error, settings, SAMPLE_ERROR)
    assert int(ours.sum()) == settings.extra_total(H * W)
    assert ours[:, : W // 4].mean() > 20 * ours[:, W // 2:].mean()


def test_settings_errors_name_the_field():
    with pytest.raises(WgpuRtError, match="budget 40"):
        AdaptiveSettings(budget=40)
    with pytest.raises(WgpuRtError, match="'random'"):
        AdaptiveSettings(sampler="random")
    with pytest.raises(WgpuRtError, match="needs a budget"):
        AdaptiveSettings(sampler="uniform")
    with pytest.raises(WgpuRtError, match="uniform_share 1.5"):
        AdaptiveSettings(budget=4.0, uniform_share=1.5)


def spill_rounds_run(gpu, importance, settings) -> int:
    """How many spill rounds a budget map switched on (their dispatch arguments are non-zero)."""
    buffers = FrameBuffers(gpu, W, H)
    write_plane(buffers, HEAT, importance)
    extra_pass = ExtraSamplesPass(gpu, W, H, settings, HEAT)
    encoder = gpu.device.create_command_encoder()
    extra_pass.execute(encoder, buffers)
    gpu.device.queue.submit([encoder.finish()])
    slots = len(extra_pass.spill_rounds) + 1
    grids = [gpu.read(b, np.uint32, shape=(slots, 6))[:, 0] for b in extra_pass.spill_args]
    return sum(int(grids[slot % 2][slot] > 0) for slot in range(len(extra_pass.spill_rounds)))


def test_spill_rounds_run_only_when_capped_pixels_leave_samples_over(gpu):
    """The usual map (nothing capped) dispatches no spill round; a budget that caps the hot pixels
    runs a few, not all cap + 1."""
    settings = AdaptiveSettings(budget=4.0)
    assert spill_rounds_run(gpu, heatmap(), settings) == 0
    peaked = np.zeros((H, W), np.float32)
    peaked[:3, :3] = 1.0                       # 9 pixels claim everything: most of the budget spills
    spilled = spill_rounds_run(gpu, peaked, settings)
    assert 0 < spilled < len(ExtraSamplesPass(gpu, W, H, settings).spill_rounds)


def test_exponent_defaults_per_mode():
    """No budget: the issue's floor(heat^3 · 31); under a budget: heat^2 and the half-buffer error^1 (see
    AdaptiveSettings.exponent); an explicit k wins in both. Pooling only under a budget, only for heat."""
    assert AdaptiveSettings().exponent == 3.0
    assert AdaptiveSettings(budget=4.0).exponent == 2.0
    assert AdaptiveSettings(sampler="variance", budget=4.0).exponent == 1.0
    assert AdaptiveSettings(budget=4.0, k=2.5).exponent == 2.5
    assert AdaptiveSettings(budget=4.0).evenly_spread == 0.5
    assert AdaptiveSettings(budget=4.0, uniform_share=0.25).evenly_spread == 0.25
    assert AdaptiveSettings(budget=4.0).pooling == 2.0
    assert AdaptiveSettings(budget=4.0, pool_sigma=0.0).pooling == 0.0
    assert AdaptiveSettings(sampler="variance", budget=4.0).pooling == 0.0
    assert AdaptiveSettings(pool_sigma=3.0).pooling == 0.0
    assert AdaptiveSettings(sampler="uniform", budget=4.0, uniform_share=0.2).evenly_spread == 1.0


def test_extra_bound_holds_every_map(gpu):
    """The bound the targeted pass sizes its batches by: a budget's exact total, else the cap everywhere."""
    assert AdaptiveSettings(budget=4.0).extra_bound(H * W) == 3 * H * W
    assert AdaptiveSettings().extra_bound(H * W) == MAX_HEAT_SAMPLES * H * W
    hot = np.ones((H, W), np.float32)
    assert int(extra_on_gpu(gpu, hot, AdaptiveSettings()).sum()) == AdaptiveSettings().extra_bound(H * W)


def test_budget_shares_follow_the_default_power_of_heat(gpu):
    """Under a budget with the default power (2), no even share and no pooling, a pixel with twice the
    heat gets four times the samples."""
    heat = np.full((H, W), 0.25, np.float32)
    heat[:, : W // 2] = 0.5
    settings = AdaptiveSettings(budget=6.0, uniform_share=0.0, pool_sigma=0.0)   # 5 extra on average: 8, 2
    ours = extra_on_gpu(gpu, heat, settings)
    assert ours[:, : W // 2].mean() == pytest.approx(4 * ours[:, W // 2:].mean(), rel=0.02)


class FixedHeat:
    """An error predictor stand-in: the same heatmap whatever the probe."""

    def __init__(self, gpu, heat):
        self.output = gpu.upload(heat.astype(np.float32))

    def record(self, encoder, input_buffer, height, width):
        return self.output


@pytest.mark.parametrize("sampler", ["heat", "uniform", "variance"])
def test_adaptive_samples_continue_the_probe_sequence(gpu, sampler):
    """A pixel that took n samples in the adaptive frame (probe + targeted pass) holds exactly what a
    brute-force n-spp render holds there: the targeted samples are numbered right after the probe's, so
    the pixel's samples are the same stratified prefix of its sequence as brute force's (no index is
    skipped, none repeated), and uniform at an integer budget is brute force."""
    from wgpu_rt.accel.geometry import GeometryBuffers
    from wgpu_rt.frame.pipeline import FramePipeline
    from wgpu_rt.renderer import render
    from wgpu_rt.scene.builtin import builtin_scene
    from wgpu_rt.trace.trace_pass import TracePass

    scene, size, seed = builtin_scene("cornell"), 16, 7
    geometry = GeometryBuffers.build(scene, 0)
    heat = np.zeros((size, size), np.float32)
    heat[:, : size // 2] = 1.0
    pipeline = FramePipeline(gpu, size, size,
                             lambda f, _: TracePass(gpu, scene, geometry, size, size, max_depth=3, seed=seed),
                             adaptive=AdaptiveSettings(sampler=sampler, budget=3.0),
                             error_predictor=FixedHeat(gpu, heat) if sampler == "heat" else None,
                             operator=None)
    pipeline.render(scene, 0)
    spp = pipeline.buffers.read(SPP.name)[0]
    radiance = pipeline.buffers.read(RADIANCE.name).transpose(1, 2, 0)
    assert int(spp.sum()) == 3 * size * size
    for count in np.unique(spp):
        brute = render(scene, spp=int(count), size=(size, size), max_depth=3, seed=seed, aovs=()).color
        where = spp == count
        np.testing.assert_allclose(radiance[where], brute[where], rtol=1e-5, atol=1e-6,
                                   err_msg=f"{sampler}: pixels with {count} samples")
