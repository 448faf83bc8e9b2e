"""Loading the networks, and ``denoise()``: one image through the denoiser off the frame loop
(pack → run → unpack, and on large frames the low band of coarser passes: frame/lowband.py),
for the ``denoise`` command, training's validation, benchmarks and tests.

The padding rule is the engine's: a network whose pooling needs H and W to be multiples of some size
runs on a canvas padded up to them by repeating the last row and column (``nn_kernels/pack.wgsl``),
and its output is cropped back. ``pad_to_multiple`` is the same rule in numpy, for running the network
elsewhere (torch, onnxruntime) on the same input.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import ModelError
from ..models import network_named
from .atrous import atrous_filter
from .chroma import match_sample_chroma
from .lowband import fewest_samples, low_band_denoise, low_band_levels
from .pack import pack_denoiser_input
from .unpack import unpack_denoiser_output


# Denoiser quality → passes of its self-ensemble (nn.WgslModel's ``ensemble``): "high" averages the image
# denoised as given and turned three ways, 4× the work for 0.35 dB on held-out worlds (BENCHMARKS.md §10).
QUALITIES = {"balanced": 1, "high": 4}


def load_model(name: str, precision: str = "auto", models_dir=None, path=None, ctx=None, required: bool = True,
               quality: str = "balanced"):
    """A ``WgslModel`` of network ``name`` from ``path``, else from ``models_dir`` (default: the shipped
    models), running ``quality``'s ensemble (QUALITIES). A missing file is a ModelError naming it, or None
    when not ``required``."""
    if quality not in QUALITIES:
        raise ModelError(f"quality {quality!r}: choose one of {', '.join(QUALITIES)}")
    network = network_named(name)
    chosen = Path(path) if path else network.path(models_dir)
    if not chosen.is_file():
        if required:
            hint = "" if path else f" (train one with `wgpu-rt train {network.cli_name}`)"
            raise ModelError(f"{chosen}: no such model file{hint}")
        return None
    from ..nn import WgslModel

    return WgslModel(chosen, precision, ctx=ctx, ensemble=QUALITIES[quality])


def denoise(model, color, albedo, normal, depth, spp=1, low_band=None, chroma: bool = True,
            post_filter: bool = True) -> np.ndarray:
    """(H, W, 3) linear HDR colour of ``spp`` samples per pixel (one count, or an (H, W[, 1]) map) +
    G-buffers → the denoised (H, W, 3) colour (finite, ≥ 0). ``model`` runs (N, C, H, W) batches; one with
    fewer ``input_channels`` (10: trained before the sample-count plane existed) gets the first ones.
    ``low_band``: take the band below quarter resolution from the denoiser run again at half (and
    quarter) resolution (frame/lowband.py; None: for frames whose sides are at least LOW_BAND_MIN_SIDE and
    whose pixels hold fewer than LOW_BAND_MAX_SPP samples somewhere).
    ``chroma``: hold the result's colour balance to the samples' block means (frame/chroma.py).
    ``post_filter``: then smooth it by the edge-aware à-trous filter (frame/atrous.py)."""
    channels = getattr(model, "input_channels", None)

    def run(packed):
        return np.asarray(model(packed[None, :channels]), np.float32)[0]

    denoised = unpack_denoiser_output(run(pack_denoiser_input(color, albedo, normal, depth, spp)), albedo)
    levels = low_band_levels(denoised.shape[1], denoised.shape[0], low_band, fewest_samples(spp))
    if levels:
        denoised = low_band_denoise(run, denoised, color, albedo, normal, depth, spp, levels)
    if chroma:
        denoised = match_sample_chroma(denoised, color)
    return atrous_filter(denoised, albedo, normal, depth, spp) if post_filter else denoised


def pad_to_multiple(x: np.ndarray, multiple: int) -> np.ndarray:
    """The engine's canvas in numpy: edge-pad (N, C, H, W) so H and W are multiples of ``multiple``."""
    pad_h, pad_w = (-x.shape[2]) % multiple, (-x.shape[3]) % multiple
    return np.pad(x, ((0, 0), (0, 0), (0, pad_h), (0, pad_w)), mode="edge") if pad_h or pad_w else x
