"""An albedo of a few point samples a pixel → an estimate of each pixel's area mean.

The denoiser was trained on the albedo of our aux pass, which estimates the mean over each pixel's area.
An albedo that averages a pixel's own few point samples (another renderer's, or ours without the aux pass)
has the jagged edges of those samples, and remodulating by it puts the jags into the result: 2–3 dB at
1 spp on Mitsuba 3's files. ``area_averaged_albedo`` smooths it by a Gaussian of POINT_ALBEDO_SIGMA pixels
over the square root of the samples (picked on four scenes, checked on three more: BENCHMARKS.md §37);
``AreaAlbedoPass`` does it on the device, each pixel by its own sample count, for frames traced without
the aux pass (``wgsl/frame/area_albedo.wgsl``).
"""

from __future__ import annotations

import numpy as np

from ..passes import ALBEDO, SPP, ComputePass, PlaneSpec
from .kernel import FrameKernel, gaussian_taps, nonnegative_finite, separable_blur

POINT_ALBEDO_SIGMA = 0.9
NEGLIGIBLE_SIGMA = 0.1   # below this, a Gaussian of a pixel's neighbours is the pixel
# The tracer's own albedo (a running mean of point samples), kept while ALBEDO holds the smoothed one.
POINT_ALBEDO = PlaneSpec("point albedo", 3)
ROWS_SMOOTHED = PlaneSpec("albedo smoothed along rows", 3)


def area_averaged_albedo(albedo: np.ndarray, samples) -> np.ndarray:
    """(H, W, C) albedo averaging ``samples`` point samples a pixel → an estimate of each pixel's area mean:
    blurred by a Gaussian of POINT_ALBEDO_SIGMA / sqrt(samples) pixels (edges repeat the border); as given
    for ``samples`` 0 (already area-averaged, as our aux pass's) or many. ``samples`` an (H, W[, 1]) map:
    each pixel by its own count, along the rows and then the columns, as the device pass (the albedo
    sanitised first: NaN/Inf and negatives count as 0)."""
    if np.ndim(samples) == 0:
        sigma = POINT_ALBEDO_SIGMA / np.sqrt(samples) if samples > 0 else 0.0
        if sigma < NEGLIGIBLE_SIGMA:
            return albedo
        return separable_blur(albedo, gaussian_taps(sigma, int(np.ceil(3 * sigma)))).astype(np.float32)
    counts = np.asarray(samples, np.float64).reshape(np.shape(albedo)[:2])
    sigma = np.where(counts > 0, POINT_ALBEDO_SIGMA / np.sqrt(np.maximum(counts, 1)), 0.0)
    smoothed = nonnegative_finite(albedo).astype(np.float64)
    for axis in (1, 0):
        smoothed = _blur_along(smoothed, sigma, axis)
    return smoothed.astype(np.float32)


def _blur_along(values: np.ndarray, sigma: np.ndarray, axis: int) -> np.ndarray:
    """Each pixel's Gaussian of its own ``sigma`` along ``axis``, out to ceil(3σ) pixels, indices clamped."""
    radius = int(np.ceil(3 * POINT_ALBEDO_SIGMA))
    length = values.shape[axis]
    reach = np.ceil(3 * sigma)
    safe = np.where(sigma >= NEGLIGIBLE_SIGMA, sigma, 1.0)
    total, weights = np.zeros_like(values), np.zeros(sigma.shape)
    for k in range(-radius, radius + 1):
        weight = np.where((sigma >= NEGLIGIBLE_SIGMA) & (abs(k) <= reach), np.exp(-k * k / (2 * safe * safe)),
                          float(k == 0))
        shifted = np.take(values, np.clip(np.arange(length) + k, 0, length - 1), axis=axis)
        total += weight[..., None] * shifted
        weights += weight
    return total / weights[..., None]


class AreaAlbedoPass(ComputePass):
    """``area_averaged_albedo`` on the device for a frame traced without the aux pass: the tracer's ALBEDO
    is kept in POINT_ALBEDO and replaced by its smoothing (each pixel by its own SPP) for the passes after;
    ``restore`` puts the tracer's own back once they have read it, so that an AOV read back and the samples
    a static view adds next frame are the tracer's."""

    inputs = (ALBEDO, SPP)
    outputs = (ALBEDO, POINT_ALBEDO)

    def __init__(self, ctx, width: int, height: int):
        constants = {"SIGMA": POINT_ALBEDO_SIGMA, "NEGLIGIBLE": NEGLIGIBLE_SIGMA}
        self.rows, self.columns = (FrameKernel(ctx, "frame/area_albedo.wgsl", entry, ("spp", "source", "smoothed"),
                                               width, height, constants) for entry in ("blur_rows", "blur_columns"))

    def execute(self, encoder, buffers) -> None:
        albedo, kept = buffers.get(ALBEDO), buffers.get(POINT_ALBEDO)
        encoder.copy_buffer_to_buffer(albedo, 0, kept, 0, albedo.size)
        spp, across = buffers.get(SPP), buffers.get(ROWS_SMOOTHED)
        self.rows.dispatch(encoder, {"spp": spp, "source": kept, "smoothed": across})
        self.columns.dispatch(encoder, {"spp": spp, "source": across, "smoothed": albedo})

    @staticmethod
    def restore(encoder, buffers) -> None:
        """Put the tracer's own albedo (POINT_ALBEDO) back into ALBEDO."""
        albedo = buffers.get(ALBEDO)
        encoder.copy_buffer_to_buffer(buffers.get(POINT_ALBEDO), 0, albedo, 0, albedo.size)
