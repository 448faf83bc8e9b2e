"""The denoise chain's full-resolution steps over bands of rows, for frames whose packed denoiser input does not
fit one storage binding (11 planes of f32: 44 bytes a pixel, so on lavapipe's 128 MiB anything past about
3 million pixels, a 2560×1440 frame; GPUs bind gigabytes).

Only the steps that hold wide per-pixel planes run in bands: pack → network → unpack (DENOISER_INPUT), and the
post filter (its 8-plane guides). The frame's white balance and exposure, its depth maximum, the low band (at
half and quarter resolution), the chroma hold and the hand-over read whole-frame planes of at most three
channels, so they run on the whole frame as before. Each band reads its rows with rows of context above and
below (the network's: its receptive radius in whole multiples of its pooling multiple, so that every band's
pooling grid lies on the frame's; the post filter's, in taller bands of its own: its reach) and keeps only its
own rows: the kept rows are what the whole frame would give. Rows move between the frame's planes and a band's
with buffer copies, one per channel (planes are planar, so a channel's rows are contiguous)."""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import DeviceLimitError
from ..passes import DTYPE_BYTES, ComputePass, FrameBuffers, PlaneSpec, prepare_network
from .atrous import GUIDE_BYTES, STEPS, AtrousPass
from .kernel import ceil_div
from .pack import PackDenoiserPass
from .planes import DENOISED, DENOISER_INPUT, INVERSE_SQRT_SPP, SAMPLES_PLANE
from .unpack import UnpackPass

ATROUS_REACH = 2 * sum(STEPS)         # the post filter's 5×5 taps STEP apart, over its steps
NETWORK_INPUTS = PackDenoiserPass.inputs
FILTERED = PlaneSpec("filtered", 3)   # the post filter's kept rows, until every band has read its context


@dataclass(frozen=True)
class Band:
    """Rows [top, bottom) read, [start, stop) kept."""

    top: int
    start: int
    stop: int
    bottom: int

    @property
    def rows(self) -> int:
        return self.bottom - self.top


def plan_bands(height: int, rows: int, halo: int, alignment: int) -> list[Band]:
    """Bands of at most ``rows`` rows (rounded down to ``alignment``) covering ``height`` rows, each keeping
    what lies ``halo`` rows or more from its cut edges (a frame edge is not cut); every band but the last
    reads exactly ``rows``, and each one's top is a multiple of ``alignment`` when ``halo`` is."""
    rows = rows // alignment * alignment
    bands, start = [], 0
    while start < height:
        top = max(0, start - halo)
        bottom = min(height, top + rows)
        stop = height if bottom == height else bottom - halo
        if stop <= start:
            raise DeviceLimitError(f"a frame {height} rows high cannot be denoised in bands of {max(rows, 0)} rows "
                                   f"with {halo} rows of context either side: the frame is too wide for this device")
        bands.append(Band(top, start, stop, bottom))
        start = stop
    return bands


def copy_rows(encoder, spec: PlaneSpec, width: int, source, source_height: int, source_row: int,
              destination, destination_height: int, destination_row: int, rows: int, channels=None) -> None:
    """Rows [source_row, source_row + rows) of every channel of a ``spec`` plane into the same channel of
    ``destination`` from ``destination_row`` (or, by ``channels``, (source channel, destination channel)
    pairs), the two planes ``source_height`` and ``destination_height`` rows high."""
    row_bytes = width * DTYPE_BYTES[spec.dtype]
    for read, write in [(c, c) for c in range(spec.channels)] if channels is None else channels:
        encoder.copy_buffer_to_buffer(source, (read * source_height + source_row) * row_bytes, destination,
                                      (write * destination_height + destination_row) * row_bytes, rows * row_bytes)


def needs_bands(ctx, width: int, height: int) -> bool:
    """Whether a width×height frame's packed denoiser input is too large for one storage binding."""
    limit = ctx.binding_limit
    return DENOISER_INPUT.nbytes(width, height) > limit


class _NetworkBand:
    """The passes of one network band height: its planes, pack and unpack."""

    def __init__(self, ctx, width: int, rows: int, depth_max, balance):
        self.buffers = FrameBuffers(ctx, width, rows)
        self.pack = PackDenoiserPass(ctx, width, rows, depth_max, balance)
        self.unpack = UnpackPass(ctx, width, rows, balance)


class _FilterBand:
    """The passes of one post filter band height: its planes and the filter."""

    def __init__(self, ctx, width: int, rows: int, balance):
        self.buffers = FrameBuffers(ctx, width, rows)
        self.post_filter = AtrousPass(ctx, width, rows, balance)


class InBands:
    """The chain's full-resolution steps for a width×height frame in bands: ``network`` (pack, ``denoiser``,
    unpack into DENOISED, and the packed 1/sqrt(spp) plane into INVERSE_SQRT_SPP for the low band) and, where
    ``post_filter``, a pass of that name (DENOISED smoothed, through FILTERED), each in bands of its own: the
    network's with its receptive radius of context, the post filter's (whose widest plane, its guides, holds 8
    floats a pixel, so its bands are taller) with its reach. ``depth_max`` and ``balance`` are the whole frame's."""

    def __init__(self, ctx, width: int, height: int, denoiser, depth_max, balance, post_filter: bool):
        self.width, self.height, self.denoiser = width, height, denoiser
        multiple = denoiser.graph.multiple
        limit = ctx.binding_limit
        rows = limit // DENOISER_INPUT.nbytes(width, 1)
        if hasattr(denoiser, "rows_in_one_pass"):   # bands the network runs whole, not in bands of its own
            rows = min(rows, denoiser.rows_in_one_pass(width))
        self.bands = plan_bands(height, rows, ceil_div(denoiser.graph.receptive_radius, multiple) * multiple,
                                multiple)
        self.passes = {band.rows: _NetworkBand(ctx, width, band.rows, depth_max, balance) for band in self.bands}
        self.filter_bands = plan_bands(height, limit // (GUIDE_BYTES * width), ATROUS_REACH, 1) \
            if post_filter else []
        self.filter_passes = {band.rows: _FilterBand(ctx, width, band.rows, balance) for band in self.filter_bands}
        self.post_filter = _PostFilterInBands(self) if post_filter else None

    def prepare(self) -> None:
        """Build ahead the network's plans at each band height (DenoiseChain.prepare)."""
        for rows, passes in self.passes.items():
            prepare_network(self.denoiser, passes.buffers.get(DENOISER_INPUT), rows, self.width)

    def _load(self, encoder, buffers, band: Band, held: FrameBuffers, specs) -> FrameBuffers:
        for spec in specs:
            copy_rows(encoder, spec, self.width, buffers.get(spec), self.height, band.top, held.get(spec), band.rows,
                      0, band.rows)
        return held

    def _keep(self, encoder, band: Band, spec: PlaneSpec, held: FrameBuffers, destination, channels=None) -> None:
        copy_rows(encoder, spec, self.width, held.get(spec), band.rows, band.start - band.top, destination,
                  self.height, band.start, band.stop - band.start, channels)

    def network(self, encoder, buffers) -> None:
        for band in self.bands:
            passes = self.passes[band.rows]
            held = self._load(encoder, buffers, band, passes.buffers, NETWORK_INPUTS)
            passes.pack.execute(encoder, held)
            output = self.denoiser.record(encoder, held.get(DENOISER_INPUT), band.rows, self.width)
            passes.unpack.execute(encoder, held, output)
            self._keep(encoder, band, DENOISED, held, buffers.get(DENOISED))
            self._keep(encoder, band, DENOISER_INPUT, held, buffers.get(INVERSE_SQRT_SPP),
                       channels=[(SAMPLES_PLANE, 0)])

    def filter(self, encoder, buffers) -> None:
        for band in self.filter_bands:
            passes = self.filter_passes[band.rows]
            held = self._load(encoder, buffers, band, passes.buffers, AtrousPass.inputs)
            passes.post_filter.execute(encoder, held)
            self._keep(encoder, band, DENOISED, held, buffers.get(FILTERED))
        encoder.copy_buffer_to_buffer(buffers.get(FILTERED), 0, buffers.get(DENOISED), 0,
                                      DENOISED.nbytes(self.width, self.height))


class _PostFilterInBands(ComputePass):
    """The post filter (frame/atrous.py) of a frame in bands, as the chain runs it: DENOISED smoothed."""

    inputs = AtrousPass.inputs
    outputs = (DENOISED,)

    def __init__(self, bands: InBands):
        self.bands = bands

    def execute(self, encoder, buffers) -> None:
        self.bands.filter(encoder, buffers)
