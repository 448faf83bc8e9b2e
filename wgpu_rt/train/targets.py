"""Training targets derived from gold renders (numpy; also the benchmarks' ground truth).

- ``error_heatmap``: where a 1-spp render is wrong: |log1p(noisy) − log1p(gold)| averaged over
  channels, divided by the image's 99th percentile and clipped, so it is a [0, 1] heatmap whose ranks
  (what adaptive sampling uses) do not depend on the image's exposure.
- ``disocclusion_mask``: where history cannot be trusted: gold frame t, warped into frame t+1 by the
  exact motion vectors of frame t+1, disagrees with gold frame t+1 (disocclusion, lighting change), or
  the pixel came from outside the previous frame.
"""

from __future__ import annotations

import numpy as np

from ..frame.pack import log_color

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


def disocclusion_mask(gold_previous, gold_current, motion_current,
                      threshold: float = DISAGREEMENT_THRESHOLD) -> np.ndarray:
    """(H, W) float32, 1 where the reprojected previous gold frame disagrees with the current one."""
    warped, valid = reproject(gold_previous, motion_current)
    disagreement = np.mean(np.abs(log_color(warped) - log_color(gold_current)), axis=0)
    return ((disagreement > threshold) | ~valid).astype(np.float32)
