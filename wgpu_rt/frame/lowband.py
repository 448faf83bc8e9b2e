"""The denoised frame's low band from the denoiser run again at half (and quarter) resolution.

The denoiser was trained on renders of 96–192 pixels, and on larger frames it leaves low-frequency
residue (blotches about its reach wide, colour drifting over large flat surfaces): OIDN's lead over it
at 1 spp grows from 128² to 512². Run on the frame averaged down 2×2, the same network sees 4× the
samples per pixel and twice the scene per receptive field, so its coarse band is cleaner, while its fine
detail is lost. The frame keeps its own detail and takes its band below quarter resolution from the
half-resolution pass (``transfer_low_band``) by a weight w = 1/spp (a low band itself: the mean over the
same blocks, so an adaptive sample map does not print its pixels into the correction): the residue
falls with the samples, the half-resolution pass's own bias does not. BENCHMARKS.md §16: at 1 spp +0.59
dB over 13 scenes at 256², +1.26 over 6 at 512², +1.2 to +3.9 on three at 1024², at 4 spp +0.08 at 256²;
at 128² (forced) −0.09 on the mean and −1.8 on `sun-room`, so frames with a side under LOW_BAND_MIN_SIDE
go without, and so do frames whose every pixel holds LOW_BAND_MAX_SPP samples or more (w ≤ 1/16: it added
0.01 dB at 256² and at most 0.02 at 512² there, §17), which spares a static view accumulating in temporal
mode the coarser passes' whole cost from its 16th sample on. The half-resolution level takes its own low band from a quarter-resolution one in turn when
its sides reach LOW_BAND_MIN_SIDE too (frames of 512² and up; its weight is 1/(4·spp)): +0.08 to +0.32
dB more at 512² and 1024², where a fourth level added nothing, so at most LOW_BAND_LEVELS coarser
levels. On lavapipe at 1080p the two cost 0.36× the denoiser's GPU time (0.29× the half-resolution one
alone).

On the device: ``LowBand`` (``pack.PackLevelPass``, the denoiser on each coarser canvas, ``UnpackPass``,
then ``LowBandPass`` from the coarsest level up); ``low_band_denoise`` with ``transfer_low_band`` and
``pack.pack_level_input`` is the numpy reference.
"""

from __future__ import annotations

import numpy as np

from ..errors import WgpuRtError
from ..passes import ALBEDO, DEPTH, NORMAL, RADIANCE, SPP, ComputePass, prepare_network
from .kernel import TILE, FrameKernel, ceil_div, nonnegative_finite
from .pack import (AS_TUNED, KEY_RATIO, PackLevelPass, block_mean, exposure_or_as_tuned, level_sample_counts,
                   pack_level_input, steps_scale)
from .planes import DENOISED, DENOISER_INPUT, INVERSE_SQRT_SPP, SAMPLES_PLANE
from .unpack import UnpackPass, unpack_denoiser_output

LOW_BAND_EPSILON = 1e-3    # radiance added to both low bands: a black level, so near-black blocks keep F;
                           # times the frame's pack.steps_scale, so that it scales with the frame's light
LOW_BAND_MIN_SIDE = 256    # "auto" takes the low band for frames (and levels) at least this wide and high
LOW_BAND_LEVELS = 2        # coarser levels at most (half and quarter resolution)
LOW_BAND_MAX_SPP = 16      # "auto" leaves out frames whose every pixel holds at least this many samples
F32_MAX = float(np.finfo(np.float32).max)
LOW_BAND_SETTINGS = {"auto": None, "on": True, "off": False}   # a --low-band flag → the low_band option


def uses_low_band(width: int, height: int, setting=None, min_spp: float = 1) -> bool:
    """Whether a width×height frame whose every pixel holds at least ``min_spp`` samples takes the low
    band: ``setting`` True or False, or None (auto: when both sides are at least LOW_BAND_MIN_SIDE and
    ``min_spp`` is under LOW_BAND_MAX_SPP)."""
    if setting is None:
        return min(width, height) >= LOW_BAND_MIN_SIDE and min_spp < LOW_BAND_MAX_SPP
    if not isinstance(setting, bool):
        raise WgpuRtError(f"low_band must be True, False or None (auto), got {setting!r}")
    return setting


def low_band_levels(width: int, height: int, setting=None, min_spp: float = 1) -> int:
    """How many coarser levels (half, quarter resolution) the frame's denoiser runs on: none unless
    ``uses_low_band``; then the half-resolution level, and the next while the level above it has both
    sides at least LOW_BAND_MIN_SIDE, up to LOW_BAND_LEVELS."""
    levels = int(uses_low_band(width, height, setting, min_spp))
    while levels and levels < LOW_BAND_LEVELS and min(ceil_div(width, 2 ** levels),
                                                       ceil_div(height, 2 ** levels)) >= LOW_BAND_MIN_SIDE:
        levels += 1
    return levels


def fewest_samples(spp) -> float:
    """The smallest sample count of one count or an (H, W[, 1]) map (non-finite entries count as 0)."""
    counts = np.asarray(spp, np.float64)
    return float(np.nan_to_num(counts, nan=0.0, posinf=0.0, neginf=0.0).min(initial=np.inf)) if counts.size else 0.0


def bilinear_up(image: np.ndarray, factor: int, shape: tuple[int, int]) -> np.ndarray:
    """(h, w, C) block values → (H, W, C), bilinear between block centres (clamped at the edges), each
    output pixel at ((x + 0.5) / factor − 0.5) in block coordinates."""
    def weights(count: int, blocks: int):
        u = np.clip((np.arange(count) + 0.5) / factor - 0.5, 0.0, blocks - 1)
        first = np.floor(u).astype(np.int64)
        return first, np.minimum(first + 1, blocks - 1), (u - first)

    rows0, rows1, ty = weights(shape[0], image.shape[0])
    cols0, cols1, tx = weights(shape[1], image.shape[1])
    image = np.asarray(image, np.float64)
    top = image[rows0] * (1 - ty[:, None, None]) + image[rows1] * ty[:, None, None]
    return top[:, cols0] * (1 - tx[None, :, None]) + top[:, cols1] * tx[None, :, None]


def transfer_low_band(denoised: np.ndarray, coarse: np.ndarray, spp=1, exposure: float = AS_TUNED) -> np.ndarray:
    """(H, W, 3) denoised radiance F of a level, (ceil(H/2), ceil(W/2), 3) radiance C of the next coarser
    one and the level's samples per pixel (one count or an (H, W[, 1]) map) → F · (w·LC + (1 − w)·LF + ε) /
    (LF + ε), with LF, LC and w the means of F, C (replicated to F's size) and 1/spp over 4×4 pixels,
    bilinear between block centres, ε LOW_BAND_EPSILON times the frame's ``exposure`` as pack.steps_scale
    has it (float32, finite, ≥ 0)."""
    height, width = denoised.shape[:2]
    full = nonnegative_finite(denoised)
    replicated = np.repeat(np.repeat(nonnegative_finite(coarse), 2, axis=0), 2, axis=1)[:height, :width]
    low_full = bilinear_up(block_mean(full, 4), 4, (height, width))
    low_coarse = bilinear_up(block_mean(replicated, 4), 4, (height, width))
    counts = level_sample_counts(spp, (height, width), 1)
    w = bilinear_up(block_mean((1.0 / np.maximum(np.nan_to_num(counts, nan=1.0), 1.0))[..., None], 4), 4,
                    (height, width))
    epsilon = np.float32(LOW_BAND_EPSILON) * np.float32(steps_scale(exposure))
    ratio = np.minimum((w * low_coarse + (1 - w) * low_full + epsilon) / (low_full + epsilon), F32_MAX)
    return np.minimum(full * ratio, F32_MAX).astype(np.float32)


def low_band_denoise(run, denoised, color, albedo, normal, depth, spp, levels: int, balance,
                     exposure: float = AS_TUNED) -> np.ndarray:
    """``denoised`` (the frame's denoiser output, unpacked) with the low band of ``levels`` coarser levels:
    each denoised by ``run`` (packed (11, h, w) input → (3, h, w) output) on the frame averaged over
    2^k × 2^k blocks, balanced by the frame's own gains (``balance``, pack.white_balance_gains), then from the
    coarsest up each level takes its band below quarter resolution from the next (``transfer_low_band``,
    the level's own summed sample counts, the frame's ``exposure``)."""
    shape = np.shape(color)[:2]
    radiance = [denoised]
    for level in range(1, levels + 1):
        packed = pack_level_input(color, albedo, normal, depth, spp, 2 ** level, balance)
        radiance.append(unpack_denoiser_output(run(packed), packed[3:6].transpose(1, 2, 0), balance))
    for level in reversed(range(levels)):
        radiance[level] = transfer_low_band(radiance[level], radiance[level + 1],
                                            level_sample_counts(spp, shape, 2 ** level), exposure)
    return radiance[0]


class LowBandPass(ComputePass):
    """One step on a width×height level: ``fine`` (its denoised radiance, rewritten), ``coarse`` (the next
    coarser level's radiance) and ``fine_input`` (the level's packed denoiser input, whose 1/sqrt(spp)
    plane, its ``samples_plane``, gives w) are buffers given to ``execute``; ``exposure``: a
    WhiteBalancePass's result, whose fourth value is the frame's exposure scale (None: pack.AS_TUNED, ε as it is)."""

    def __init__(self, ctx, width: int, height: int, exposure=None, samples_plane: int = SAMPLES_PLANE):
        self.exposure = exposure_or_as_tuned(ctx, exposure)
        self.blocks = (ceil_div(width, 4), ceil_div(height, 4))
        self.means_buffer = ctx.storage(4 * 7 * self.blocks[0] * self.blocks[1], label="low band means")
        constants = {"EPSILON": LOW_BAND_EPSILON, "KEY_RATIO": KEY_RATIO, "SAMPLES_PLANE": samples_plane}
        self.means = FrameKernel(ctx, "frame/lowband.wgsl", "low_band_means",
                                 ("fine", "coarse", "fine_input", "means"), width, height, constants)
        self.apply = FrameKernel(ctx, "frame/lowband.wgsl", "low_band_apply", ("fine", "means", "exposure"),
                                 width, height, constants)

    def execute(self, encoder, fine, coarse, fine_input) -> None:
        bound = {"fine": fine, "coarse": coarse, "fine_input": fine_input, "means": self.means_buffer,
                 "exposure": self.exposure}
        self.means.dispatch(encoder, bound, groups=(ceil_div(self.blocks[0], TILE), ceil_div(self.blocks[1], TILE)))
        self.apply.dispatch(encoder, bound)


class LowBand(ComputePass):
    """The low band of a frame's denoised radiance on the device (``low_band_denoise``'s steps): for each of
    ``levels`` coarser levels its pack (``self.packs``), ``denoiser`` on that canvas and an unpack into the
    level's own radiance buffer; then, from the coarsest up, a LowBandPass per level, the last on the
    frame's denoised plane in place (read against the frame's packed input, DENOISER_INPUT, or where
    ``in_bands`` the 1/sqrt(spp) plane of it that frame/bands.py keeps). ``depth_max`` and ``balance`` are the
    full frame's (pack.DepthMaxPass's and pack.WhiteBalancePass's results: its gains, and its exposure scale
    for the steps' ε)."""

    outputs = (DENOISED,)

    def __init__(self, ctx, width: int, height: int, depth_max, balance, denoiser, levels: int,
                 in_bands: bool = False):
        self.denoiser = denoiser
        self.samples = INVERSE_SQRT_SPP if in_bands else DENOISER_INPUT
        self.inputs = (RADIANCE, ALBEDO, NORMAL, DEPTH, SPP, self.samples, DENOISED)
        self.packs = [PackLevelPass(ctx, width, height, depth_max, balance, 2 ** level)
                      for level in range(1, levels + 1)]
        self.unpacks = [UnpackPass(ctx, *pack.size, balance, albedo_plane=3) for pack in self.packs]
        self.radiance = [ctx.storage(DENOISED.nbytes(*pack.size), label=f"denoised, level {level}")
                         for level, pack in enumerate(self.packs, 1)]
        sizes = [(width, height)] + [pack.size for pack in self.packs[:-1]]
        self.steps = [LowBandPass(ctx, *size, balance, 0 if level == 0 and in_bands else SAMPLES_PLANE)
                      for level, size in enumerate(sizes)]

    def prepare(self) -> None:
        """Build ahead the denoiser's plans for the coarser levels (see DenoiseChain.prepare)."""
        for pack in self.packs:
            width, height = pack.size
            prepare_network(self.denoiser, pack.result, height, width)

    def execute(self, encoder, buffers) -> None:
        for pack, unpack, radiance in zip(self.packs, self.unpacks, self.radiance):
            pack.execute(encoder, buffers)
            width, height = pack.size
            unpack.unpack(encoder, self.denoiser.record(encoder, pack.result, height, width), pack.result, radiance)
        fines = [buffers.get(DENOISED)] + self.radiance[:-1]
        inputs = [buffers.get(self.samples)] + [pack.result for pack in self.packs[:-1]]
        for step, fine, coarse, fine_input in reversed(list(zip(self.steps, fines, self.radiance, inputs))):
            step.execute(encoder, fine, coarse, fine_input)
