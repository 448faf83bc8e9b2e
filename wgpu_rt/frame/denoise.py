"""Loading the networks, and ``denoise()``: one image through the denoiser off the frame loop
(white balance → pack → run → unpack, and on large frames the low band of coarser passes: frame/lowband.py,
then the chroma hold and the post filter), for the ``denoise`` command, the confidence model's training data,
benchmarks and tests. A model of the WGSL engine runs all of it on the device with the frame loop's own passes
(``DenoiseOnDevice``: the image uploaded once, the result read back once); any other model (torch,
onnxruntime) takes the numpy references of those passes.

The padding rule is the engine's: a network whose pooling needs H and W to be multiples of some size
runs on a canvas padded up to them by repeating the last row and column (``nn_kernels/pack.wgsl``),
and its output is cropped back. ``pad_to_multiple`` is the same rule in numpy, for running the network
elsewhere (torch, onnxruntime) on the same input.
"""

from __future__ import annotations

import weakref
from pathlib import Path

import numpy as np

from ..errors import ModelError
from ..models import network_named
from ..passes import ALBEDO, DEPTH, NORMAL, RADIANCE, SPP, FrameBuffers
from .adaptive import HALF_RADIANCE
from .area_albedo import area_averaged_albedo
from .atrous import atrous_filter
from .chroma import match_sample_chroma
from .converge import HALF_SPP, converge
from .denoise_chain import DenoiseChain, reads_at_one_key
from .lowband import fewest_samples, low_band_denoise, low_band_levels
from .pack import DepthMaxPass, frame_exposure, pack_denoiser_input, white_balance_gains
from .planes import write_plane
from .unpack import unpack_denoiser_output


def escaped_albedo(albedo: np.ndarray, color: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """Where nothing was hit (depth 0) and the albedo is black, as other renderers write the sky's, the
    albedo our tracer gives there (wgsl/trace/guide_albedo.wgsl): the colour, which is the background's
    radiance, at most 1. Otherwise the network, trained on ours, reads the sky's colour divided by
    pack.ALBEDO_EPSILON (+0.6 dB on gold-bunny-sky from Mitsuba at 1 spp, BENCHMARKS.md §37)."""
    escaped = (depth[..., 0] <= 0) & (albedo.max(axis=-1) <= 0)
    if not escaped.any():
        return albedo
    result = albedo.copy()
    result[escaped] = np.clip(color[escaped], 0.0, 1.0)
    return result


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
            post_filter: bool = True, half=None, white_balance: bool = True,
            auto_exposure: bool | None = None) -> np.ndarray:
    """(H, W, 3) linear HDR colour of ``spp`` samples per pixel (one count, or an (H, W[, 1]) map) +
    G-buffers → the denoised (H, W, 3) colour (finite, ≥ 0). ``model`` runs (N, C, H, W) batches; one with
    fewer ``input_channels`` (10: trained before the sample-count plane existed) gets the first ones.
    ``low_band``: take the band below quarter resolution from the denoiser run again at half (and
    quarter) resolution (frame/lowband.py; None: for frames whose sides are at least LOW_BAND_MIN_SIDE and
    whose pixels hold fewer than LOW_BAND_MAX_SPP samples somewhere).
    ``chroma``: hold the result's colour balance to the samples' block means (frame/chroma.py).
    ``post_filter``: then smooth it by the edge-aware à-trous filter (frame/atrous.py).
    ``white_balance``: the network reads the irradiance divided by the frame's gains, and its output is
    multiplied back (frame/pack.py's ``white_balance_gains``); False: gains of 1.
    ``auto_exposure``: the gains also bring the frame's irradiance to one key (pack.py's ``exposure_scale``),
    so that a frame reads the same at any scale of its light; None: as the model was trained
    (``trained_auto_exposure``).
    ``half``: (the mean after the first part of the samples, its (H, W) counts): each pixel then hands over
    to the samples' own mean where that has converged, as a denoised render of several samples does
    (frame/converge.py)."""
    height, width = color.shape[:2]
    auto_exposure = reads_at_one_key(model, auto_exposure)
    levels = low_band_levels(width, height, low_band, fewest_samples(spp))
    counts = device_sample_counts(spp, (height, width))
    half_counts = None if half is None else device_sample_counts(half[1], (height, width))
    if hasattr(model, "record") and counts is not None and (half is None or half_counts is not None):
        on_device = DenoiseOnDevice.for_model(model, width, height, levels, chroma, post_filter, half is not None,
                                              white_balance, auto_exposure)
        return on_device(color, albedo, normal, depth, counts, None if half is None else (half[0], half_counts))
    channels = getattr(model, "input_channels", None)

    def run(packed):
        return np.asarray(model(packed[None, :channels]), np.float32)[0]

    balance = white_balance_gains(color, albedo, white_balance, auto_exposure)
    exposure = frame_exposure(color, albedo)
    denoised = unpack_denoiser_output(run(pack_denoiser_input(color, albedo, normal, depth, spp, balance=balance)),
                                      albedo, balance)
    if levels:
        denoised = low_band_denoise(run, denoised, color, albedo, normal, depth, spp, levels, balance, exposure)
    if chroma:
        denoised = match_sample_chroma(denoised, color, exposure)
    if post_filter:
        denoised = atrous_filter(denoised, albedo, normal, depth, spp, exposure)
    if half is None:
        return denoised
    samples = np.broadcast_to(np.asarray(spp)[..., 0] if np.ndim(spp) == 3 else spp, (height, width))
    return converge(denoised, color, samples, half[0], np.asarray(half[1]).reshape(height, width))


def denoise_render(model, color, albedo, normal, depth, spp=1, albedo_samples=None, **options) -> np.ndarray:
    """``denoise()`` of an image as a renderer wrote it: its albedo taken from the colour where paths escaped
    with a black albedo (``escaped_albedo``), then averaged over each pixel's area from ``albedo_samples`` point
    samples a pixel (frame/area_albedo.py; 0: already such a mean, as our aux pass writes it; None: the
    colour's samples, the median of a map, as another renderer's albedo holds). ``depth`` None (a renderer
    that writes OIDN's three inputs only): one distance everywhere, every pixel a surface (BENCHMARKS.md §46:
    0.23 / 0.25 dB lower at 1 / 4 spp on the mean of nine scenes, 0.93 at most)."""
    if depth is None:
        depth = np.ones(color.shape[:2] + (1,), np.float32)
    if albedo_samples is None:
        albedo_samples = float(np.median(spp))
    albedo = area_averaged_albedo(escaped_albedo(albedo, color, depth), albedo_samples)
    return denoise(model, color, albedo, normal, depth, spp, **options)


def device_sample_counts(spp, shape: tuple[int, int]) -> np.ndarray | None:
    """``spp`` (one count or an (H, W[, 1]) map) as the (H, W) u32 counts of the device's sample-count
    planes, or None where such a plane cannot hold it exactly (a count that is not a whole number in u32's
    range): the numpy path then takes it as given."""
    counts = np.broadcast_to(np.asarray(spp, np.float64).reshape(np.shape(spp)[:2] or ()), shape)
    if not (np.isfinite(counts).all() and (counts >= 0).all() and (counts < 2 ** 32).all()
            and (counts == np.round(counts)).all()):
        return None
    return counts.astype(np.uint32)


# How many sizes and settings ``DenoiseOnDevice.for_model`` keeps set up per model: a run over images of many sizes
# (a folder of renders) holds the planes of the last few, not of every size it met.
KEPT_SIZES = 4


class DenoiseOnDevice:
    """``denoise`` for a model of the WGSL engine at one image size: the frame loop's depth maximum and
    denoise chain (frame/denoise_chain.py: the low band's ``levels``, the hand-over to converged samples
    where ``converging``) in one command buffer over uploaded planes, the result read back. ``for_model``
    keeps one per model and setting (the KEPT_SIZES used last), so that a benchmark's images of one size
    reuse the passes; they hold the model by a weak proxy, so that the cache does not keep a model alive
    (nor its device buffers) once its user lets it go."""

    _made: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()   # model -> {settings: DenoiseOnDevice}

    @classmethod
    def for_model(cls, model, width: int, height: int, levels: int, chroma: bool, post_filter: bool,
                  converging: bool = False, white_balance: bool = True, auto_exposure: bool = True):
        made = cls._made.setdefault(model, {})
        key = (width, height, levels, chroma, post_filter, converging, white_balance, auto_exposure)
        if key not in made:
            while len(made) >= KEPT_SIZES:   # the longest unused goes, with its device buffers
                del made[next(iter(made))]
            made[key] = cls(weakref.proxy(model), width, height, levels, chroma, post_filter, converging,
                            white_balance, auto_exposure)
        made[key] = made.pop(key)   # now the most recently used
        return made[key]

    def __init__(self, model, width: int, height: int, levels: int, chroma: bool, post_filter: bool,
                 converging: bool = False, white_balance: bool = True, auto_exposure: bool = True):
        self.ctx = model.ctx
        self.buffers = FrameBuffers(self.ctx, width, height)
        self.depth_max = DepthMaxPass(self.ctx, width, height)
        self.chain = DenoiseChain(self.ctx, width, height, model, self.depth_max.result, levels, chroma, post_filter,
                                  converging, white_balance, auto_exposure)

    def __call__(self, color, albedo, normal, depth, counts: np.ndarray, half=None) -> np.ndarray:
        """``half``: (mean, u32 counts) after the first part of the samples, when ``converging``."""
        planes = [(RADIANCE, color), (ALBEDO, albedo), (NORMAL, normal), (DEPTH, depth), (SPP, counts)]
        if half is not None:
            planes += [(HALF_RADIANCE, half[0]), (HALF_SPP, half[1])]
        for spec, image in planes:
            write_plane(self.buffers, spec, image)
        encoder = self.ctx.device.create_command_encoder(label="wgpu-rt denoise")
        self.depth_max.execute(encoder, self.buffers)
        self.chain.record(encoder, self.buffers)
        self.ctx.device.queue.submit([encoder.finish()])
        return np.ascontiguousarray(self.buffers.read(self.chain.output.name).transpose(1, 2, 0))


def pad_to_multiple(x: np.ndarray, multiple: int) -> np.ndarray:
    """The engine's canvas in numpy: edge-pad (N, C, H, W) so H and W are multiples of ``multiple``."""
    pad_h, pad_w = (-x.shape[2]) % multiple, (-x.shape[3]) % multiple
    return np.pad(x, ((0, 0), (0, 0), (0, pad_h), (0, pad_w)), mode="edge") if pad_h or pad_w else x
