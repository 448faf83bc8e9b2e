"""What follows the tracer when a frame is denoised, in order: the white balance and exposure (frame/pack.py),
pack, the network, unpack, the low band's coarser levels (frame/lowband.py), the chroma hold
(frame/chroma.py), the post filter (frame/atrous.py) and the hand-over to converged samples
(frame/converge.py). The frame loop records it between the tracer and the temporal pass (``FramePipeline``),
``denoise()`` over uploaded planes (``frame.denoise.DenoiseOnDevice``), so both run one chain in one order. A frame
whose packed input is wider than one storage binding runs pack, network, unpack and the post filter in bands of
rows (frame/bands.py)."""

from __future__ import annotations

from ..passes import Stage, prepare_network
from .atrous import AtrousPass
from .chroma import ChromaPass
from .converge import CONVERGED, ConvergePass
from .lowband import LowBand
from .bands import NETWORK_INPUTS, InBands, needs_bands
from .pack import PackDenoiserPass, WhiteBalancePass
from .planes import DENOISED, DENOISER_INPUT, INVERSE_SQRT_SPP
from .unpack import UnpackPass


# The ONNX metadata key that says whether a network (denoiser, error predictor, confidence model) was trained on
# inputs brought to one exposure (frame/pack.py's exposure_scale, radiance_exposure): "on" or "off"; models from
# before it say nothing and read "off".
INPUT_EXPOSURE = "wgpu_rt.auto_exposure"


def trained_auto_exposure(model) -> bool:
    """Whether ``model`` (a WGSL engine model, or anything with its ``graph``) was trained with the exposure
    step: its ONNX file's INPUT_EXPOSURE metadata."""
    return getattr(getattr(model, "graph", None), "metadata", {}).get(INPUT_EXPOSURE) == "on"


def reads_at_one_key(model, auto_exposure: bool | None) -> bool:
    """Whether ``model`` reads its input at one key: ``auto_exposure`` (the caller's ``auto_exposure=`` /
    ``--auto-exposure on|off``), or where None (auto) as it was trained (``trained_auto_exposure``)."""
    return trained_auto_exposure(model) if auto_exposure is None else auto_exposure


def _no_mark(encoder, name: str) -> None:
    """A stage boundary nobody times."""


class DenoiseChain:
    """The chain for ``denoiser`` at width×height; ``depth_max`` is a DepthMaxPass's result, recorded
    earlier in the same encoder. ``levels``: the low band's coarser levels (0: none); ``chroma``,
    ``post_filter``, ``converge``, ``white_balance``, ``auto_exposure``: whether those steps run (without
    the white balance and the exposure the network reads the irradiance as it is: gains of 1; the pass
    that finds them runs anyway, for the frame's exposure scale the low band, chroma hold and post filter
    read).
    ``output`` is the plane the chain leaves its result in."""

    def __init__(self, ctx, width: int, height: int, denoiser, depth_max, levels: int = 0, chroma: bool = True,
                 post_filter: bool = True, converge: bool = False, white_balance: bool = True,
                 auto_exposure: bool = True):
        self.width, self.height, self.denoiser = width, height, denoiser
        self.balance = WhiteBalancePass(ctx, width, height, white_balance, auto_exposure)
        gains = self.balance.result   # and the frame's exposure scale
        # a frame whose packed input is wider than one storage binding runs its full-resolution steps in bands
        self.bands = InBands(ctx, width, height, denoiser, depth_max, gains, post_filter) \
            if needs_bands(ctx, width, height) else None
        whole = self.bands is None
        self.pack = PackDenoiserPass(ctx, width, height, depth_max, gains) if whole else None
        self.unpack = UnpackPass(ctx, width, height, gains) if whole else None
        self.low_band = LowBand(ctx, width, height, depth_max, gains, denoiser, levels, in_bands=not whole) \
            if levels else None
        self.chroma = ChromaPass(ctx, width, height, gains) if chroma else None
        self.post_filter = (AtrousPass(ctx, width, height, gains) if whole else self.bands.post_filter) \
            if post_filter else None
        self.converge = ConvergePass(ctx, width, height) if converge else None
        self.output = CONVERGED if converge else DENOISED

    def stages(self) -> list:
        """Its passes in order (a Stage stands in for the network, and for the steps run in bands), for
        frame.pipeline.check_wiring."""
        network = [self.pack, Stage("denoiser", (DENOISER_INPUT,), ()), self.unpack] if self.bands is None \
            else [Stage("denoiser in bands", NETWORK_INPUTS, (DENOISED, INVERSE_SQRT_SPP))]
        steps = (self.low_band, self.chroma, self.post_filter, self.converge)
        return [self.balance, *network, *(step for step in steps if step is not None)]

    def prepare(self, buffers) -> None:
        """Build ahead what the chain's first ``record`` would for its networks (frame.pipeline's
        ``prepare``): the denoiser at the frame's size (or its bands') and at each coarser level's."""
        if self.bands is None:
            prepare_network(self.denoiser, buffers.get(DENOISER_INPUT), self.height, self.width)
        else:
            self.bands.prepare()
        if self.low_band is not None:
            self.low_band.prepare()

    def record(self, encoder, buffers, low_band: bool = True, mark=_no_mark) -> None:
        """Record the chain into ``encoder`` over ``buffers``' planes (the low band only where
        ``low_band``), calling ``mark(encoder, name)`` at the end of each timed stage (a frame in bands
        times its packing with the network)."""
        self.balance.execute(encoder, buffers)
        if self.bands is None:
            self.pack.execute(encoder, buffers)
            mark(encoder, "pack")
            network_output = self.denoiser.record(encoder, buffers.get(DENOISER_INPUT), self.height, self.width)
            mark(encoder, "denoise")
            self.unpack.execute(encoder, buffers, network_output)
        else:
            self.bands.network(encoder, buffers)
            mark(encoder, "denoise")
        steps = (("low band", self.low_band if low_band else None), ("chroma", self.chroma),
                 ("post filter", self.post_filter), ("converge", self.converge))
        for name, step in steps:
            if step is not None:
                step.execute(encoder, buffers)
                mark(encoder, name)
