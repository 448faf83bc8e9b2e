"""Training targets derived from gold renders (numpy; also the benchmarks' ground truth).

- ``error_heatmap``: where a 1-spp render is wrong: |log1p(noisy) − log1p(gold)| averaged over
  channels, divided by the image's 99th percentile and clipped, so it is a [0, 1] heatmap whose ranks
  (what adaptive sampling uses) do not depend on the image's exposure.
- ``disocclusion_mask``: where history cannot be trusted: gold frame t, warped into frame t+1 by the
  exact motion vectors of frame t+1, disagrees with gold frame t+1 (disocclusion, lighting change), or
  the pixel came from outside the previous frame.
- ``runtime_history``: what the confidence model is shown at runtime: the temporal pass's reprojection
  (frame/temporal.py's reference of frame/temporal.wgsl: bilinear, only texels passing the depth/normal
  tests, zero where none does) of frame t, so training and evaluation see the runtime's input.
"""

from __future__ import annotations

import numpy as np

from ..frame.pack import log_color
from ..frame.temporal import reproject_history

HEATMAP_PERCENTILE = 99.0
DISAGREEMENT_THRESHOLD = 0.1    # mean |Δ log1p RGB| above which history is wrong


def error_heatmap(noisy, gold) -> np.ndarray:
    """(H, W) float32 in [0, 1]: the normalized log-space error of ``noisy`` against ``gold``."""
    error = np.mean(np.abs(log_color(noisy) - log_color(gold)), axis=0)
    scale = float(np.percentile(error, HEATMAP_PERCENTILE))
    if scale <= 0.0:
        return np.zeros_like(error, np.float32)
    return np.clip(error / scale, 0.0, 1.0).astype(np.float32)


def reproject(previous, motion) -> tuple[np.ndarray, np.ndarray]:
    """Warp ``previous`` (H, W, C) into the current frame with ``motion`` (H, W, 2, previous minus
    current position in pixels; x right, y down), bilinearly. Returns (warped, valid) where ``valid``
    (H, W) is False where the source position lies outside the previous frame."""
    previous = np.asarray(previous, np.float32)
    height, width = previous.shape[:2]
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float32)
    # Pixel centres sit at integer + 0.5; sample positions are in the same convention.
    sx = xs + motion[..., 0]
    sy = ys + motion[..., 1]
    valid = (sx >= -0.5) & (sx <= width - 0.5) & (sy >= -0.5) & (sy <= height - 0.5)
    sx = np.clip(sx, 0, width - 1)
    sy = np.clip(sy, 0, height - 1)
    x0 = np.floor(sx).astype(np.int64)
    y0 = np.floor(sy).astype(np.int64)
    x1 = np.minimum(x0 + 1, width - 1)
    y1 = np.minimum(y0 + 1, height - 1)
    fx = (sx - x0)[..., None]
    fy = (sy - y0)[..., None]
    warped = ((1 - fx) * (1 - fy) * previous[y0, x0] + fx * (1 - fy) * previous[y0, x1]
              + (1 - fx) * fy * previous[y1, x0] + fx * fy * previous[y1, x1])
    return warped.astype(np.float32), valid


def disocclusion_mask(gold_previous, gold_current, motion_current, threshold: float = DISAGREEMENT_THRESHOLD,
                      blur_sigma: float = 0.0) -> np.ndarray:
    """(H, W) float32, 1 where the reprojected previous gold frame disagrees with the current one.
    ``blur_sigma`` > 0 compares both log1p images after a Gaussian blur of that many pixels: gold's own
    noise averages out (so it stops flagging pixels), while a real change of the history, which covers
    several pixels with a large difference, stays above the threshold (spread by about the blur)."""
    from scipy.ndimage import gaussian_filter

    warped, valid = reproject(gold_previous, motion_current)
    previous, current = log_color(warped), log_color(gold_current)
    if blur_sigma > 0:
        previous, current = (gaussian_filter(image, (0, blur_sigma, blur_sigma)) for image in (previous, current))
    disagreement = np.mean(np.abs(previous - current), axis=0)
    return ((disagreement > threshold) | ~valid).astype(np.float32)


def runtime_history(previous_color, previous_gbuffers: dict, current_gbuffers: dict, motion_current):
    """(history RGB (H, W, 3), history depth (H, W, 1), valid (H, W)) as the runtime's temporal pass
    reprojects frame t into frame t+1: ``previous_color`` with frame t's depth and normal (the history's
    planes), tested against frame t+1's depth and normal; zero and not valid where no texel passes
    (disoccluded, or from outside frame t). The temporal pass takes the current frame there whatever the
    confidence model says, so the model's own job is the valid pixels."""
    height, width = previous_color.shape[:2]
    history = np.concatenate([np.asarray(previous_color, np.float32),
                              np.asarray(previous_gbuffers["depth"], np.float32).reshape(height, width, 1),
                              np.asarray(previous_gbuffers["normal"], np.float32),
                              np.ones((height, width, 1), np.float32)], axis=-1)
    reprojected = reproject_history(history, current_gbuffers["depth"], current_gbuffers["normal"],
                                    np.asarray(motion_current, np.float32))
    return reprojected[..., :3], reprojected[..., 3:4], reprojected[..., 4] > 0


def confidence_pair(previous, current) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One frame pair of a dataset sequence (``Frame``s t and t+1) as the confidence model meets it:
    (history RGB, history depth, valid, disocclusion mask). History is gold frame t reprojected as the
    runtime does (``runtime_history``, with the 1-spp G-buffers the tracer hands the temporal pass);
    gold stands in for the previous denoised output."""
    motion = current.gold["motion"]
    history, history_depth, valid = runtime_history(previous.gold["color"], previous.noisy[1], current.noisy[1],
                                                    motion)
    return history, history_depth, valid, disocclusion_mask(previous.gold["color"], current.gold["color"], motion)
