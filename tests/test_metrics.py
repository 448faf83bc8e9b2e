"""Metrics against brute-force definitions and their known fixed points."""

import math

import numpy as np
import pytest

from wgpu_rt import metrics


@pytest.fixture
def images():
    rng = np.random.default_rng(3)
    ref = rng.gamma(1.0, 1.0, size=(24, 20, 3)).astype(np.float32)
    noisy = (ref * rng.uniform(0.5, 1.5, size=ref.shape)).astype(np.float32)
    return ref, noisy


def test_rel_mse_matches_a_per_pixel_loop(images):
    ref, noisy = images
    total = 0.0
    for r, t in zip(ref.ravel().tolist(), noisy.ravel().tolist()):
        total += (t - r) ** 2 / (r * r + 0.01)
    assert metrics.rel_mse(ref, noisy) == pytest.approx(total / ref.size, rel=1e-6)


def test_psnr_matches_the_tonemapped_definition(images):
    ref, noisy = images
    display = lambda x: [(max(v, 0.0) / (1 + max(v, 0.0))) ** (1 / 2.2) for v in x.ravel().tolist()]  # noqa: E731
    mse = sum((a - b) ** 2 for a, b in zip(display(ref), display(noisy))) / ref.size
    assert metrics.psnr(ref, noisy) == pytest.approx(10 * math.log10(1 / mse), rel=1e-6)
    assert metrics.psnr(ref, ref) == math.inf


def test_ssim_is_one_for_identical_and_drops_with_noise(images):
    ref, noisy = images
    assert metrics.ssim(ref, ref) == pytest.approx(1.0)
    slightly = ref * 1.02
    assert metrics.ssim(ref, noisy) < metrics.ssim(ref, slightly) < 1.0


def test_metrics_rank_a_better_estimate_higher(images):
    ref, noisy = images
    better = 0.5 * (ref + noisy)
    assert metrics.psnr(ref, better) > metrics.psnr(ref, noisy)
    assert metrics.rel_mse(ref, better) < metrics.rel_mse(ref, noisy)


@pytest.mark.skipif(not metrics.flip_available(), reason="flip-evaluator not installed")
def test_flip_is_zero_for_identical_and_positive_for_noise(images):
    ref, noisy = images
    assert metrics.flip(ref, ref) == pytest.approx(0.0, abs=1e-6)
    assert metrics.flip(ref, noisy) > metrics.flip(ref, 0.5 * (ref + noisy)) > 0.0


def test_bad_inputs_are_rejected(images):
    ref, noisy = images
    with pytest.raises(ValueError, match="shapes differ"):
        metrics.psnr(ref, noisy[:-1])
    bad = noisy.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        metrics.rel_mse(ref, bad)
