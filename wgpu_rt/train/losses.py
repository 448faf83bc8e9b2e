"""Differentiable losses in torch.

SSIM is the standard one of Wang et al. (2004): an 11×11 Gaussian window with σ = 1.5, constants
C1 = (0.01·L)², C2 = (0.03·L)² with L = 1, local statistics by a depthwise convolution, zero padding
avoided by computing only the 'valid' region (as scikit-image with its defaults crops the border).
The denoiser is trained on log1p colour, where values mostly stay in [0, 2], so L = 1 keeps the
constants in the usual proportion. Its SSIM term can instead be taken on display values (``display``:
the Reinhard + gamma 2.2 mapping of wgpu_rt.metrics, which weighs dark regions far more than log1p
does), so training optimises what the benchmarks score.

The denoiser outputs log1p *irradiance* (colour demodulated by its albedo factor, see
wgpu_rt.frame.pack); its target carries that factor, so the SSIM term is taken on the remodulated colour
(what unpack produces) while the pixel term stays on log1p irradiance (smooth, with gradients below 0).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

SSIM_WINDOW = 11
SSIM_SIGMA = 1.5
SSIM_WEIGHT = 0.8
CHARBONNIER_EPSILON = 1e-3
DISPLAY_GAMMA = 2.2
DISPLAY_EPSILON = 1e-5      # keeps the gamma curve's slope finite at black
LOWPASS_BLOCK = 8           # the block-mean term's block size (px)
MAX_LOG_IRRADIANCE = 30.0   # expm1(30) ≈ 1e13: far above any training radiance, finite in float32
LOG_MSE_FLOOR = 1e-6        # the log-MSE term's floor: a crop's display MSE below it (PSNR above 60 dB) counts little
EDGE_STEP = 0.1             # an albedo or normal plane (in [0, 1]) stepping this much between neighbours is an edge
EDGE_DEPTH_RATIO = 0.05     # so is depth changing by this fraction of the nearer pixel's
EDGE_REACH = 2              # pixels within this many of an edge (the line between two pixels) count as on it


def _gaussian_window(channels: int, dtype, device) -> torch.Tensor:
    coords = torch.arange(SSIM_WINDOW, dtype=dtype, device=device) - (SSIM_WINDOW - 1) / 2
    g = torch.exp(-coords ** 2 / (2 * SSIM_SIGMA ** 2))
    g = g / g.sum()
    return (g[:, None] * g[None, :]).expand(channels, 1, SSIM_WINDOW, SSIM_WINDOW).contiguous()


def ssim(x: torch.Tensor, y: torch.Tensor, data_range: float = 1.0) -> torch.Tensor:
    """Mean SSIM of two NCHW batches (each at least 11×11)."""
    channels = x.shape[1]
    window = _gaussian_window(channels, x.dtype, x.device)
    blur = lambda t: F.conv2d(t, window, groups=channels)  # noqa: E731
    c1, c2 = (0.01 * data_range) ** 2, (0.03 * data_range) ** 2
    mu_x, mu_y = blur(x), blur(y)
    var_x = blur(x * x) - mu_x ** 2
    var_y = blur(y * y) - mu_y ** 2
    cov = blur(x * y) - mu_x * mu_y
    index = ((2 * mu_x * mu_y + c1) * (2 * cov + c2)) / ((mu_x ** 2 + mu_y ** 2 + c1) * (var_x + var_y + c2))
    return index.mean()


def charbonnier(x: torch.Tensor, y: torch.Tensor, epsilon: float = CHARBONNIER_EPSILON) -> torch.Tensor:
    """A smooth L1: mean of sqrt((x − y)² + ε²)."""
    return torch.sqrt((x - y) ** 2 + epsilon ** 2).mean()


def log_to_display(log_color: torch.Tensor) -> torch.Tensor:
    """log1p radiance y → metrics.to_display(expm1(y)) = (1 − e^−y)^(1/2.2), with y clamped at 0 (a
    negative prediction is black on screen; the pixel term still pulls it up)."""
    reinhard = 1.0 - torch.exp(-log_color.clamp_min(0.0))
    return (reinhard + DISPLAY_EPSILON) ** (1.0 / DISPLAY_GAMMA) - DISPLAY_EPSILON ** (1.0 / DISPLAY_GAMMA)


def remodulate(log_irradiance: torch.Tensor, factor: torch.Tensor) -> torch.Tensor:
    """log1p irradiance and the albedo factor → log1p colour, as unpack computes it (clamped at 0)."""
    return torch.log1p(torch.expm1(log_irradiance.clamp(0.0, MAX_LOG_IRRADIANCE)) * factor)


def log_display_mse(prediction: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Mean over the batch of log10(1 + MSE / LOG_MSE_FLOOR), each crop's MSE taken over its display values: a
    crop's share of the gradient no longer grows with its error, so a 1 dB gain on a dark, nearly clean crop
    counts as much as one on a noisy bright crop, as a mean of PSNRs weighs them."""
    mse = ((prediction - target) ** 2).mean(dim=(1, 2, 3))
    return torch.log10(1.0 + mse / LOG_MSE_FLOOR).mean()


def aux_edges(aux: torch.Tensor) -> torch.Tensor:
    """(N, 7, H, W) albedo, normal (both in [0, 1]) and normalised depth → (N, 1, H, W) float mask, 1 within
    EDGE_REACH pixels of a silhouette or crease: an albedo or normal plane stepping EDGE_STEP or more between
    neighbours, or depth changing by EDGE_DEPTH_RATIO of the nearer one's."""
    shading, depth = aux[:, :6], aux[:, 6:7]
    edge = torch.zeros_like(depth, dtype=torch.bool)
    for dim in (2, 3):
        length = aux.shape[dim] - 1
        a, b = shading.narrow(dim, 0, length), shading.narrow(dim, 1, length)
        near, far = depth.narrow(dim, 0, length), depth.narrow(dim, 1, length)
        step = ((a - b).abs().amax(dim=1, keepdim=True) >= EDGE_STEP) | \
            ((near - far).abs() >= EDGE_DEPTH_RATIO * torch.minimum(near, far))
        edge.narrow(dim, 0, length).logical_or_(step)   # both pixels beside the step
        edge.narrow(dim, 1, length).logical_or_(step)
    return F.max_pool2d(edge.float(), 2 * EDGE_REACH - 1, stride=1, padding=EDGE_REACH - 1)


def edge_l1(prediction: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean absolute difference over the pixels ``mask`` marks (all channels); 0 where it marks none."""
    return ((prediction - target).abs() * mask).sum() / (mask.sum() * prediction.shape[1]).clamp_min(1.0)


def denoiser_loss(prediction: torch.Tensor, target: torch.Tensor, pixel_loss: str = "l1",
                  ssim_space: str = "log", lowpass: float = 0.0, log_mse: float = 0.0, edge: float = 0.0,
                  aux: torch.Tensor | None = None) -> torch.Tensor:
    """0.8·(1 − SSIM) + 0.2·(L1 or Charbonnier) [+ lowpass · L1 of 8×8 block means] [+ log_mse ·
    ``log_display_mse``] [+ edge · L1 of display colours on ``aux_edges(aux)``]. ``prediction``:
    (N, 3, H, W) log1p irradiance; ``target``: (N, 6, H, W), the gold log1p irradiance and the albedo
    factor. The pixel term compares log1p irradiance; SSIM compares the remodulated colours, in log1p or
    (``ssim_space="display"``) display values; the block-mean term compares the same colours averaged
    over 8×8 blocks, where low-frequency blotches that SSIM's 11-px window barely sees stand out; the log-MSE
    term and the edge term (``aux``: the input's albedo, normal and depth planes) compare display values
    whatever ``ssim_space`` is, the edge term only near the silhouettes and creases that the aux planes show,
    where the other terms' means dilute the error of a few thin pixels."""
    target, factor = target[:, :3], target[:, 3:]
    pixel = charbonnier(prediction, target) if pixel_loss == "charbonnier" else F.l1_loss(prediction, target)
    prediction, target = remodulate(prediction, factor), remodulate(target, factor)
    if ssim_space == "display":
        prediction, target = log_to_display(prediction), log_to_display(target)
    loss = SSIM_WEIGHT * (1.0 - ssim(prediction, target)) + (1.0 - SSIM_WEIGHT) * pixel
    if lowpass:
        loss = loss + lowpass * F.l1_loss(F.avg_pool2d(prediction, LOWPASS_BLOCK), F.avg_pool2d(target, LOWPASS_BLOCK))
    if (log_mse or edge) and ssim_space != "display":
        prediction, target = log_to_display(prediction), log_to_display(target)
    if log_mse:
        loss = loss + log_mse * log_display_mse(prediction, target)
    if edge:
        loss = loss + edge * edge_l1(prediction, target, aux_edges(aux))
    return loss
