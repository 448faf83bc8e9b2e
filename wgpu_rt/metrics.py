"""Image-quality metrics shared by training, benchmarks and tests.

All functions take linear HDR images as (H, W, 3) float arrays (reference first, then test) and
return a Python float. The definitions follow the denoising literature so numbers are comparable:

- ``rel_mse``: mean of (test − ref)² / (ref² + ε), ε = 0.01, per channel (Rousselle et al.). Scale
  invariant where the reference is bright, so dark and bright regions count alike.
- ``psnr`` and ``ssim`` are computed on display values: Reinhard x/(1+x), then gamma 1/2.2, which
  maps [0, ∞) to [0, 1) so the peak signal is 1 and fireflies cannot dominate.
- ``ssim`` is scikit-image's (Gaussian window, σ = 1.5, as Wang et al.), averaged over channels.
- ``flip``: NVIDIA's HDR-FLIP mean error (the optional flip-evaluator package, imported lazily;
  ``flip_available()`` says whether it can be used).

Non-finite inputs are an error (they would make every metric meaningless, silently).
"""

from __future__ import annotations

import importlib.util

import numpy as np

REL_MSE_EPSILON = 0.01
DISPLAY_GAMMA = 2.2


def _pair(reference, test) -> tuple[np.ndarray, np.ndarray]:
    ref = np.asarray(reference, dtype=np.float64)
    out = np.asarray(test, dtype=np.float64)
    if ref.shape != out.shape:
        raise ValueError(f"image shapes differ: reference {ref.shape} vs test {out.shape}")
    for name, arr in (("reference", ref), ("test", out)):
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} image has {np.count_nonzero(~np.isfinite(arr))} non-finite values")
    return ref, out


def to_display(image) -> np.ndarray:
    """Linear HDR → [0, 1) display values: Reinhard x/(1+x) then gamma 1/2.2 (negatives clamp to 0)."""
    x = np.maximum(np.asarray(image, dtype=np.float64), 0.0)
    return (x / (1.0 + x)) ** (1.0 / DISPLAY_GAMMA)


def rel_mse(reference, test, epsilon: float = REL_MSE_EPSILON) -> float:
    ref, out = _pair(reference, test)
    return float(np.mean((out - ref) ** 2 / (ref ** 2 + epsilon)))


def psnr(reference, test) -> float:
    """PSNR in dB of the display-mapped images (peak 1); ``inf`` for identical images."""
    ref, out = _pair(reference, test)
    mse = float(np.mean((to_display(out) - to_display(ref)) ** 2))
    return float("inf") if mse == 0.0 else float(10.0 * np.log10(1.0 / mse))


def ssim(reference, test) -> float:
    """Mean SSIM of the display-mapped images (scikit-image, Gaussian σ = 1.5, data range 1)."""
    from skimage.metrics import structural_similarity

    ref, out = _pair(reference, test)
    channel_axis = -1 if ref.ndim == 3 else None
    return float(structural_similarity(to_display(ref), to_display(out), data_range=1.0,
                                       channel_axis=channel_axis, gaussian_weights=True, sigma=1.5,
                                       use_sample_covariance=False))


def flip_available() -> bool:
    return importlib.util.find_spec("flip_evaluator") is not None


def flip(reference, test) -> float:
    """Mean HDR-FLIP error (0 = identical). Needs the optional ``flip-evaluator`` package."""
    if not flip_available():
        raise ImportError("FLIP needs the flip-evaluator package (pip install 'wgpu-rt[bench]')")
    import flip_evaluator

    ref, out = _pair(reference, test)
    _, mean_error, _ = flip_evaluator.evaluate(
        np.ascontiguousarray(np.maximum(ref, 0), np.float32),
        np.ascontiguousarray(np.maximum(out, 0), np.float32),
        "HDR", inputsRGB=False, applyMagma=False)
    return float(mean_error)


def all_metrics(reference, test, with_flip: bool = True) -> dict[str, float]:
    """Every metric by name; FLIP only when asked for and installed."""
    result = {"psnr": psnr(reference, test), "ssim": ssim(reference, test),
              "rel_mse": rel_mse(reference, test)}
    if with_flip and flip_available():
        result["flip"] = flip(reference, test)
    return result
