"""benchmarks/common.py: scoring against golds of few samples (twin_corrected_psnr)."""

import importlib
from pathlib import Path

import numpy as np
import pytest

from wgpu_rt import metrics

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def common(monkeypatch):
    monkeypatch.syspath_prepend(str(REPO / "benchmarks"))
    return importlib.import_module("common")


def test_twin_golds_recover_the_score_against_the_truth(common):
    """Two golds with independent noise as strong as the image's own error: against one of them the
    score is 3 dB low and two images' gap is narrowed; the twin-corrected scores match those against the
    truth within a tenth of a dB."""
    rng = np.random.default_rng(3)
    truth = rng.uniform(0.05, 2.0, (256, 256, 3))

    def noisy(sigma):
        return np.maximum(truth * (1 + sigma * rng.standard_normal(truth.shape)), 0.0)

    gold, twin = noisy(0.05), noisy(0.05)
    good, poor = noisy(0.03), noisy(0.06)
    for image in (good, poor):
        exact = metrics.psnr(truth, image)
        assert abs(common.twin_corrected_psnr(gold, twin, image) - exact) < 0.1
        assert metrics.psnr(gold, image) < exact - 1.0
    gap = metrics.psnr(truth, good) - metrics.psnr(truth, poor)
    assert metrics.psnr(gold, good) - metrics.psnr(gold, poor) < gap - 1.0
    assert common.twin_corrected_psnr(gold, twin, 0.5 * (gold + twin)) == float("inf")
