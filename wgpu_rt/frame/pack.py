"""Packing the tracer's planes into the networks' inputs, on the device and as numpy references.

Training builds its inputs with the numpy functions below, so the two sides cannot drift apart: a
change here changes both, and tests/test_frame_pack.py holds them equal.

Depth is normalised by the frame's max depth (ARCHITECTURE.md's contract), found on the device by an
atomic max over the depth's bit pattern (``wgsl/frame/depth_max.wgsl``), so no value travels to the
CPU. Sanitising: NaN/±Inf become 0 and negatives are clamped to 0 in colour, albedo and depth (a
failed sample adds nothing); non-finite normal components become 0 (mapping to 0.5).

The denoiser sees colour *demodulated* by albedo: log1p(colour / (albedo + ALBEDO_EPSILON)), the
irradiance, which is smooth across texture and material edges (those come back, noise-free, when
``unpack`` multiplies by the same factor). ALBEDO_EPSILON keeps black albedo finite. Where a path escapes,
the tracer's albedo is the background's radiance (at most 1; ``wgsl/trace/guide_albedo.wgsl``), what the
pixel's colour is a multiple of, so the irradiance stays smooth across a horizon.
The irradiance is also white-balanced: each channel divided by the frame's gain (``white_balance_gains``,
on the device ``WhiteBalancePass``), which ``unpack`` multiplies back. The shipped network, trained on
light that is mostly near white, turns strongly coloured light grey: given a 4096-spp render of a room lit
by a green wall's bounce (world-2147483667) as its input, it returned it 31 dB away. Balanced, its input
looks like what it knows (BENCHMARKS.md §27).
With the exposure step the gains also carry the frame's exposure (``exposure_scale``): the irradiance's key,
the log-average of its 8×8 tiles' mean luminance, is brought to EXPOSURE_KEY, so that the network reads a
frame at 1/64 of the light as it reads the frame itself (the network shipped before session 41, trained and
run without the step, was 13 dB lower there at 4 spp on `cornell`; a model's ONNX file says which it was
trained with, frame/denoise_chain.py's INPUT_EXPOSURE). Whether or not the gains carry it, the steps after the
network (chroma hold, low band, post filter) read the frame at STEPS_KEY by it (``steps_scale``; BENCHMARKS.md
§40).
The two small networks read log1p radiance, not demodulated; a model whose file says it was trained with the
step reads it at one key too, found by the same pass without albedo (``RadianceExposurePass``): the error
predictor its 1-spp probe at PROBE_KEY, the confidence model the denoised frame and its history at
CONFIDENCE_KEY, both by the frame's key (BENCHMARKS.md §41: trained without, they lose their savings and their
history at other scales of the light; the shipped error predictor is trained with it).
"""

from __future__ import annotations

import numpy as np

from ..passes import ALBEDO, DEPTH, NORMAL, RADIANCE, SPP, ComputePass, PlaneSpec
from .kernel import TILE, FrameKernel, ceil_div, finite, nonnegative_finite
from .planes import CONFIDENCE_INPUT, DENOISER_INPUT, ERROR_INPUT

# The bindings each entry point of frame/pack.wgsl uses (their indices are read from the WGSL).
DENOISER_BINDINGS = ("color", "albedo", "normal", "depth", "depth_max_bits", "spp", "packed", "balance")
ERROR_BINDINGS = ("color", "packed", "balance")
CONFIDENCE_BINDINGS = ("color", "depth", "depth_max_bits", "reprojected", "packed", "balance")


# -- numpy references ---------------------------------------------------------------------------------
ALBEDO_EPSILON = 0.01
WHITE_BALANCE_POWER = 0.5          # the gains are this power of the mean irradiance's channels
WHITE_BALANCE_FLOOR = 1.0 / 16.0   # no gain below this (a channel black everywhere is divided by it, not 0)
IRRADIANCE_LIMIT = 1e30            # each pixel's irradiance clamped to this in the mean (its f32 sum stays finite)
NO_BALANCE = np.ones(3, np.float32)
EXPOSURE_KEY = 0.3                 # the key the network reads: near the median of its training frames' keys
KEY_FLOOR = 1e-8                   # tiles darker than this (black, or lit by nothing) leave the key alone
EXPOSURE_LIMIT = 2.0 ** 64         # the exposure scale stays within [1 / this, this]
STEPS_KEY = 0.1                    # the key the chroma hold, low band and post filter read a frame at: their ε
                                   # and σ were tuned on the built-ins, whose keys are 0.09–0.15
KEY_RATIO = EXPOSURE_KEY / STEPS_KEY
PROBE_KEY = 0.3                    # the radiance key an error predictor trained with the step reads its 1-spp probe
                                   # at (0.03–3 tried on the one before, BENCHMARKS.md §41)
CONFIDENCE_KEY = 0.1               # the radiance key a confidence model trained with the step reads its frames at:
                                   # near the median of the training worlds' keys (0.09–0.10, §41)
AS_TUNED = 1.0 / KEY_RATIO         # the exposure scale of a frame at STEPS_KEY, which those steps read as it is


def white_balance_gains(color: np.ndarray, albedo: np.ndarray, balance: bool = True,
                        exposure: bool = True) -> np.ndarray:
    """(H, W, 3) radiance and albedo → the frame's (3,) white-balance gains: the mean of each channel of
    the irradiance (sanitised radiance / albedo_factor, each pixel clamped to IRRADIANCE_LIMIT) to the
    power WHITE_BALANCE_POWER, divided by the three's mean, at least WHITE_BALANCE_FLOOR; (1, 1, 1) for a
    black frame or without ``balance``. With ``exposure`` (as models trained since BENCHMARKS.md §40 read
    their input), all three times the frame's ``exposure_scale``."""
    if not (balance or exposure):
        return NO_BALANCE
    irradiance = np.minimum(frame_irradiance(color, albedo), IRRADIANCE_LIMIT)
    scale = exposure_scale(irradiance) if exposure else 1.0
    mean = irradiance.reshape(3, -1).mean(axis=1)
    if not (balance and mean.max() > 0.0):
        return (NO_BALANCE * scale).astype(np.float32)
    gains = mean ** WHITE_BALANCE_POWER
    return (np.maximum(gains / gains.mean(), WHITE_BALANCE_FLOOR) * scale).astype(np.float32)


def frame_irradiance(color: np.ndarray, albedo: np.ndarray) -> np.ndarray:
    """(H, W, 3) radiance and albedo → (3, H, W) float64 irradiance: sanitised radiance / albedo_factor."""
    return nonnegative_finite(color).transpose(2, 0, 1).astype(np.float64) / albedo_factor(albedo)


def frame_exposure(color: np.ndarray, albedo: np.ndarray) -> float:
    """(H, W, 3) radiance and albedo → the frame's ``exposure_scale`` (what WhiteBalancePass leaves in its
    result's fourth value, whether or not the gains carry it)."""
    return exposure_scale(np.minimum(frame_irradiance(color, albedo), IRRADIANCE_LIMIT))


def steps_scale(exposure: float) -> float:
    """How many times brighter than STEPS_KEY a frame of exposure scale ``exposure`` is (in f32, as the
    device finds it): the steps after the network scale their radiance ε by it and divide the radiance they
    compare by it."""
    return float(np.float32(exposure) * np.float32(KEY_RATIO))


def exposure_or_as_tuned(ctx, exposure=None):
    """``exposure`` (a WhiteBalancePass's result, read by the steps after the network for its fourth value,
    the frame's exposure scale), or where None a buffer whose scale is AS_TUNED: the frame read as it is."""
    if exposure is not None:
        return exposure
    return ctx.upload(np.array([1.0, 1.0, 1.0, AS_TUNED], np.float32), label="exposure as tuned")


def radiance_exposure(color: np.ndarray, key: float) -> float:
    """(H, W, 3) radiance → ``exposure_scale`` of the radiance itself (no albedo to demodulate by), to
    ``key`` (what RadianceExposurePass leaves in its result)."""
    radiance = np.minimum(nonnegative_finite(color).transpose(2, 0, 1).astype(np.float64), IRRADIANCE_LIMIT)
    return exposure_scale(radiance, key)


def probe_exposure(color: np.ndarray) -> float:
    """(H, W, 3) 1-spp radiance → the factor the error predictor's input divides it by when the model reads
    its probe at one key: ``radiance_exposure`` to PROBE_KEY."""
    return radiance_exposure(color, PROBE_KEY)


def gains_or_ones(ctx, gains=None):
    """``gains`` (a RadianceExposurePass's result, read by a small network's packing), or where None a buffer of
    gains 1: the input read as it is."""
    return gains if gains is not None else ctx.upload(NO_BALANCE, label="read as it is")


def exposure_scale(irradiance: np.ndarray, key: float = EXPOSURE_KEY) -> float:
    """(3, H, W) irradiance → the factor it is divided by so that its key becomes ``key``: the key is
    exp of the mean log of the mean luminance (the channels' mean) of each TILE×TILE tile (fewer pixels at
    the frame's right and bottom edges) brighter than KEY_FLOOR; 1 where no tile is. Tiles first, so
    that one firefly moves one tile's log, not the frame's mean; within EXPOSURE_LIMIT."""
    luminance = irradiance.mean(axis=0)
    means = block_sum(luminance, TILE) / block_sum(np.ones_like(luminance), TILE)
    tiles = means[means > KEY_FLOOR]
    if tiles.size == 0:
        return 1.0
    frame_key = float(np.exp(np.log(tiles).mean()))
    return float(np.clip(frame_key / key, 1.0 / EXPOSURE_LIMIT, EXPOSURE_LIMIT))


def albedo_factor(albedo: np.ndarray, balance: np.ndarray = NO_BALANCE) -> np.ndarray:
    """(H, W, 3) albedo → the (3, H, W) demodulation factor: albedo sanitised, clamped to [0, 1], + ε,
    times the frame's white-balance gain of each channel (``white_balance_gains``; none by default)."""
    clamped = np.clip(nonnegative_finite(albedo), 0.0, 1.0)
    factor = (clamped + np.float32(ALBEDO_EPSILON)) * np.asarray(balance, np.float32)
    return factor.transpose(2, 0, 1).astype(np.float32)


def demodulated_log_color(color: np.ndarray, albedo: np.ndarray, balance: np.ndarray = NO_BALANCE) -> np.ndarray:
    """(H, W, 3) radiance and albedo → (3, H, W) log1p of the sanitised radiance / albedo_factor (clamped
    to f32's max first: bright radiance over black albedo would overflow)."""
    irradiance = nonnegative_finite(color).transpose(2, 0, 1).astype(np.float64) / albedo_factor(albedo, balance)
    return np.log1p(np.minimum(irradiance, np.finfo(np.float32).max)).astype(np.float32)


def log_color(color: np.ndarray) -> np.ndarray:
    """(H, W, 3) radiance → (3, H, W) log1p of the sanitised radiance."""
    return np.log1p(nonnegative_finite(color)).transpose(2, 0, 1).astype(np.float32)


def normalize_depth(depth: np.ndarray, frame_max: float) -> np.ndarray:
    """(H, W) depth divided by ``frame_max`` (0 everywhere when nothing was hit)."""
    depth = nonnegative_finite(np.asarray(depth).reshape(np.shape(depth)[:2]))
    return (depth / np.float32(frame_max) if frame_max > 0 else np.zeros_like(depth)).astype(np.float32)


def frame_max_depth(depth: np.ndarray) -> float:
    return float(nonnegative_finite(depth).max(initial=0.0))


def sample_count_plane(spp, shape: tuple[int, int]) -> np.ndarray:
    """The denoiser's sample-count plane, (1, H, W): 1/sqrt(spp) per pixel (the colour's noise relative to
    one sample's), from one count for the frame or an (H, W[, 1]) map; counts below 1 count as 1."""
    counts = np.broadcast_to(np.asarray(spp, np.float64).reshape(np.shape(spp)[:2]), shape)
    return (1.0 / np.sqrt(np.maximum(np.nan_to_num(counts, nan=1.0), 1.0)))[None].astype(np.float32)


def pack_denoiser_input(color, albedo, normal, depth, spp=1, frame_max: float | None = None,
                        balance: np.ndarray | None = None) -> np.ndarray:
    """(H, W, 3) radiance, albedo, normal, (H, W[, 1]) depth and the sample count (one number, or an
    (H, W[, 1]) map as adaptive sampling makes) → the denoiser's (11, H, W) float32 input: log1p of the
    albedo-demodulated, white-balanced RGB (``balance``, default this frame's own ``white_balance_gains``),
    albedo clamped to [0, 1], normal·0.5+0.5 clamped to [0, 1], depth / frame max depth (``frame_max``,
    default this depth's own), 1/sqrt(spp) (``sample_count_plane``)."""
    clamped_albedo = np.clip(nonnegative_finite(albedo), 0.0, 1.0).transpose(2, 0, 1)
    normal = np.clip(finite(normal) * 0.5 + 0.5, 0.0, 1.0).transpose(2, 0, 1)
    depth = normalize_depth(depth, frame_max_depth(depth) if frame_max is None else frame_max)[None]
    balance = white_balance_gains(color, albedo) if balance is None else balance
    return np.concatenate([demodulated_log_color(color, albedo, balance), clamped_albedo, normal, depth,
                           sample_count_plane(spp, depth.shape[1:])]).astype(np.float32)


def block_sum(image: np.ndarray, factor: int) -> np.ndarray:
    """(H, W[, C]) → (ceil(H/factor), ceil(W/factor)[, C]) float64: each factor×factor block's sum over the
    pixels it holds (fewer at the bottom and right edges when the size is not a multiple of ``factor``)."""
    image = np.asarray(image, np.float64)
    return np.add.reduceat(np.add.reduceat(image, range(0, image.shape[0], factor), axis=0),
                           range(0, image.shape[1], factor), axis=1)


def block_mean(image: np.ndarray, factor: int) -> np.ndarray:
    """(H, W, C) → (ceil(H/factor), ceil(W/factor), C) float32: each block's mean over the pixels it holds."""
    pixels = block_sum(np.ones(np.shape(image)[:2]), factor)
    return (block_sum(image, factor) / pixels[..., None]).astype(np.float32)


def level_sample_counts(spp, shape: tuple[int, int], factor: int) -> np.ndarray:
    """The sample counts (one number or an (H, W[, 1]) map) of an (H, W) frame summed over its
    factor×factor blocks: (ceil(H/factor), ceil(W/factor)) float64."""
    return block_sum(np.broadcast_to(np.asarray(spp, np.float64).reshape(np.shape(spp)[:2]), shape), factor)


def pack_level_input(color, albedo, normal, depth, spp=1, factor: int = 2, balance: np.ndarray | None = None
                     ) -> np.ndarray:
    """The denoiser's (11, ceil(H/f), ceil(W/f)) input for the frame averaged over f×f blocks, f = ``factor``
    (a coarser level of frame/lowband.py): each pixel packs the mean of its block of frame pixels
    (sanitised colour, albedo and depth; the normals' mean renormalised, 0 where its largest component
    is under 1e-6), the block's sample counts summed, depth divided by the full frame's max, colour
    balanced by the full frame's gains (``balance``, default its ``white_balance_gains``)."""
    balance = white_balance_gains(color, albedo) if balance is None else balance
    height, width = np.shape(color)[:2]
    depth = np.asarray(depth).reshape(height, width, 1)
    normal = block_mean(finite(normal), factor).astype(np.float64)
    largest = np.abs(normal).max(axis=2, keepdims=True)
    normal = normal / np.where(largest > 1e-6, largest, np.inf)
    normal /= np.maximum(np.linalg.norm(normal, axis=2, keepdims=True), 1.0)
    return pack_denoiser_input(block_mean(nonnegative_finite(color), factor),
                               block_mean(nonnegative_finite(albedo), factor), normal,
                               block_mean(nonnegative_finite(depth), factor),
                               level_sample_counts(spp, (height, width), factor), frame_max=frame_max_depth(depth),
                               balance=balance)


def pack_error_input(color, exposure: float = 1.0) -> np.ndarray:
    """(H, W, 3) 1-spp radiance → the error predictor's (3, H, W) input: log1p RGB, divided first by
    ``exposure`` (a model that reads its probe at one key is given ``probe_exposure``; clamped to f32's max)."""
    scaled = nonnegative_finite(color).astype(np.float64) / np.float32(exposure)
    return log_color(np.minimum(scaled, np.finfo(np.float32).max).astype(np.float32))


def pack_confidence_input(color, history, depth, previous_depth, exposure: float = 1.0) -> np.ndarray:
    """The confidence predictor's (8, H, W) input: log1p current RGB, log1p reprojected history RGB (both
    divided first by ``exposure``, as ``pack_error_input``), current depth and reprojected previous depth,
    both divided by the current frame's max depth."""
    frame_max = frame_max_depth(depth)
    return np.concatenate([pack_error_input(color, exposure), pack_error_input(history, exposure),
                           normalize_depth(depth, frame_max)[None],
                           normalize_depth(previous_depth, frame_max)[None]]).astype(np.float32)


# -- passes -------------------------------------------------------------------------------------------
class DepthMaxPass(ComputePass):
    """depth → ``self.result``, a one-u32 buffer holding the bit pattern of the frame's max depth (not a
    per-pixel plane, so the pass owns it; the packing passes are handed it)."""

    inputs = (DEPTH,)

    def __init__(self, ctx, width: int, height: int):
        self.kernel = FrameKernel(ctx, "frame/depth_max.wgsl", "main", ("depth", "depth_max_bits"),
                                  width, height)
        self.result = ctx.storage(4, label="depth_max_bits")

    def execute(self, encoder, buffers) -> None:
        encoder.clear_buffer(self.result)
        self.kernel.dispatch(encoder, {"depth": buffers.get(DEPTH), "depth_max_bits": self.result})


class WhiteBalancePass(ComputePass):
    """radiance, albedo → ``self.result``, a buffer of the frame's three white-balance gains (1 without
    ``balance``), times its exposure scale where ``exposure`` (``white_balance_gains``), then that scale
    itself (``frame_exposure``), found by frame/balance.wgsl: per-tile sums, then one workgroup's
    reduction; not a per-pixel plane, so the pass owns it; the denoiser's packing and unpacking passes read
    the gains, the chroma hold, low band and post filter the scale. ``key``: the key the scale brings the
    frame to; without ``demodulate`` it is the colour's own key, not its irradiance's (RadianceExposurePass)."""

    inputs = (RADIANCE, ALBEDO)

    def __init__(self, ctx, width: int, height: int, balance: bool = True, exposure: bool = True,
                 key: float = EXPOSURE_KEY, demodulate: bool = True):
        constants = {"POWER": WHITE_BALANCE_POWER, "FLOOR": WHITE_BALANCE_FLOOR, "BALANCE": balance,
                     "EXPOSURE": exposure, "KEY": key, "KEY_FLOOR": KEY_FLOOR,
                     "EXPOSURE_LIMIT": EXPOSURE_LIMIT, "DEMODULATE": demodulate}
        self.demodulate = demodulate
        self.tile_kernel = FrameKernel(ctx, "frame/balance.wgsl", "tile_sums_main", ("color", "albedo", "tile_sums"),
                                       width, height, constants)
        self.gains_kernel = FrameKernel(ctx, "frame/balance.wgsl", "gains_main", ("tile_sums", "balance"),
                                        width, height, constants)
        tiles = ceil_div(width, TILE) * ceil_div(height, TILE)
        self.tile_sums = ctx.storage(4 * 3 * tiles, label="irradiance tile sums")
        self.result = ctx.storage(4 * 4, label="white balance and exposure")

    def execute(self, encoder, buffers) -> None:
        color = buffers.get(self.inputs[0])
        albedo = buffers.get(ALBEDO) if self.demodulate else color   # not read without demodulate
        planes = {"color": color, "albedo": albedo, "tile_sums": self.tile_sums, "balance": self.result}
        self.tile_kernel.dispatch(encoder, planes)
        self.gains_kernel.dispatch(encoder, planes, groups=(1, 1))


class RadianceExposurePass(WhiteBalancePass):
    """``color`` (a 3-plane radiance, the tracer's by default) → ``self.result``: ``radiance_exposure`` to
    ``key`` as three equal gains, then again (the colour's own key, no albedo: the shader is handed the
    colour in its place and reads none), for a network that reads its input at one key (the error
    predictor's probe at PROBE_KEY, the confidence predictor's denoised frame at CONFIDENCE_KEY)."""

    def __init__(self, ctx, width: int, height: int, key: float = PROBE_KEY, color: PlaneSpec = RADIANCE):
        super().__init__(ctx, width, height, balance=False, exposure=True, key=key, demodulate=False)
        self.inputs = (color,)


class PackDenoiserPass(ComputePass):
    """radiance, albedo, normal, depth, spp → denoiser_input (11 planes); ``depth_max`` is a DepthMaxPass's
    result and ``balance`` a WhiteBalancePass's, recorded earlier in the same encoder. A denoiser trained
    without the sample-count plane (10 inputs, models before it) reads the first 10 planes, which are laid
    out as before."""

    inputs = (RADIANCE, ALBEDO, NORMAL, DEPTH, SPP)
    outputs = (DENOISER_INPUT,)

    def __init__(self, ctx, width: int, height: int, depth_max, balance):
        self.depth_max, self.balance = depth_max, balance
        self.kernel = FrameKernel(ctx, "frame/pack.wgsl", "pack_denoiser", DENOISER_BINDINGS, width, height)

    def execute(self, encoder, buffers) -> None:
        self.kernel.dispatch(encoder, {
            "color": buffers.get(RADIANCE), "albedo": buffers.get(ALBEDO), "normal": buffers.get(NORMAL),
            "depth": buffers.get(DEPTH), "depth_max_bits": self.depth_max, "spp": buffers.get(SPP),
            "packed": buffers.get(DENOISER_INPUT), "balance": self.balance})


class PackLevelPass(ComputePass):
    """radiance, albedo, normal, depth, spp → ``self.result``, the denoiser's input for the frame averaged
    over ``factor``×``factor`` blocks (``self.size``: ceil(W/factor)×ceil(H/factor); not a frame-sized
    plane, so the pass owns it); ``depth_max`` and ``balance`` (the full frame's) as for PackDenoiserPass."""

    inputs = (RADIANCE, ALBEDO, NORMAL, DEPTH, SPP)

    def __init__(self, ctx, width: int, height: int, depth_max, balance, factor: int):
        self.depth_max, self.balance = depth_max, balance
        self.size = (ceil_div(width, factor), ceil_div(height, factor))
        self.result = ctx.storage(DENOISER_INPUT.nbytes(*self.size), label=f"denoiser_input, {factor}x{factor} blocks")
        self.kernel = FrameKernel(ctx, "frame/pack.wgsl", "pack_denoiser_level", DENOISER_BINDINGS, width, height,
                                  constants={"LEVEL_FACTOR": factor})

    def execute(self, encoder, buffers) -> None:
        self.kernel.dispatch(encoder, {
            "color": buffers.get(RADIANCE), "albedo": buffers.get(ALBEDO), "normal": buffers.get(NORMAL),
            "depth": buffers.get(DEPTH), "depth_max_bits": self.depth_max, "spp": buffers.get(SPP),
            "packed": self.result, "balance": self.balance},
            groups=(ceil_div(self.size[0], TILE), ceil_div(self.size[1], TILE)))


class PackErrorPass(ComputePass):
    """radiance → error_input (3 planes of log1p RGB divided by ``exposure``, a RadianceExposurePass's result
    recorded earlier in the same encoder; None: read as it is)."""

    inputs = (RADIANCE,)
    outputs = (ERROR_INPUT,)

    def __init__(self, ctx, width: int, height: int, exposure=None):
        self.exposure = gains_or_ones(ctx, exposure)
        self.kernel = FrameKernel(ctx, "frame/pack.wgsl", "pack_error", ERROR_BINDINGS, width, height)

    def execute(self, encoder, buffers) -> None:
        self.kernel.dispatch(encoder, {"color": buffers.get(RADIANCE), "packed": buffers.get(ERROR_INPUT),
                                       "balance": self.exposure})


class PackConfidencePass(ComputePass):
    """``color`` (the current denoised frame), ``reprojected`` history (frame/temporal.wgsl's planes),
    depth → confidence_input; ``depth_max`` as for PackDenoiserPass; both colours divided by ``exposure``
    (a RadianceExposurePass's result recorded earlier in the same encoder; None: read as they are)."""

    def __init__(self, ctx, width: int, height: int, color, reprojected, depth_max, exposure=None):
        self.color, self.reprojected, self.depth_max = color, reprojected, depth_max
        self.exposure = gains_or_ones(ctx, exposure)
        self.inputs = (color, reprojected, DEPTH)
        self.outputs = (CONFIDENCE_INPUT,)
        self.kernel = FrameKernel(ctx, "frame/pack.wgsl", "pack_confidence", CONFIDENCE_BINDINGS, width, height)

    def execute(self, encoder, buffers) -> None:
        self.kernel.dispatch(encoder, {
            "color": buffers.get(self.color), "reprojected": buffers.get(self.reprojected),
            "depth": buffers.get(DEPTH), "depth_max_bits": self.depth_max,
            "packed": buffers.get(CONFIDENCE_INPUT), "balance": self.exposure})
