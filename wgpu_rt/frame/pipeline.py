"""The frame: trace → pack → denoiser → unpack (→ low band) → temporal → tone-map, recorded into one command encoder
per frame, with exactly one readback (the frame's HDR colour unless ``hdr=False``, the AOVs asked for,
the display image and the per-stage timestamps ride in one buffer).

Frames in flight: ``frames()`` records frame N+1 while frame N runs, submits it the moment frame N's
readback is mapped, and copies frame N out while N+1 runs, into two readback buffers used in turn. N+1
is not submitted earlier because mapping a buffer waits for all work submitted so far (wgpu-py polls the
device until its queue is idle): submitted first, frame N+1 would finish before frame N could be read,
and the device would sit idle while the host copies frame N out.

Networks are objects with ``record(encoder, input_buffer, height, width) -> output_buffer`` (the NN
engine's ``wgpu_rt.nn.WgslModel``), and may have ``prepare(input_buffer, height, width)``, which builds
ahead what their first ``record`` would (``FramePipeline.prepare``). Stage timings come from timestamp
queries when the adapter has them: an empty compute pass with a timestamp write marks each stage
boundary, so stages recorded by other packages are timed too.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import wgpu

from ..errors import ModelError, WgpuRtError
from ..passes import (ALBEDO, DEPTH, MOTION, NORMAL, NUMPY_DTYPE, RADIANCE, SPP, FrameBuffers, PlaneSpec, Stage,
                      prepare_network)
from ..trace.trace_pass import SampleSchedule, TracePass
from .adaptive import HALF_RADIANCE, HEAT, SAMPLE_ERROR, AdaptiveSettings, ExtraSamplesPass, HalfBufferErrorPass
from .area_albedo import AreaAlbedoPass
from .converge import HALF_SPP, copy_half, half_count
from .denoise_chain import DenoiseChain, reads_at_one_key
from .interleave import InterleavePass, interleaved, interleaves
from .lowband import low_band_levels, uses_low_band
from .pack import DepthMaxPass, PackErrorPass, RadianceExposurePass
from .planes import ERROR_INPUT
from .temporal import TEMPORAL, TemporalPass, TemporalSettings, frame_change
from .tonemap import TonemapPass

# half_radiance and half_spp: the mean after the first half of the samples (see frame/converge.py),
# so that `wgpu-rt denoise` can hand over to an EXR's own mean as a denoised render does.
# (RADIANCE: the samples' mean before the denoiser, the colour itself when nothing denoises it)
AOV_PLANES = {plane.name: plane for plane in (ALBEDO, NORMAL, DEPTH, MOTION, SPP, HALF_RADIANCE, HALF_SPP, RADIANCE)}
SAMPLES_PER_SUBMIT = 1 << 21   # pixel samples per command buffer (a fraction of a second on lavapipe)
PROGRESS_SECONDS = 0.25        # how often a long frame waits for the device to tell its progress


@dataclass
class RenderResult:
    """One rendered frame."""

    frame: int
    color: np.ndarray | None                            # (H, W, 3) float32 linear HDR: the frame's final
                                                        # colour; None when not read back (hdr=False)
    aovs: dict[str, np.ndarray] = field(default_factory=dict)   # name → (H, W, C) float32
    image: np.ndarray | None = None                     # (H, W, 4) display image when tone-mapped
    stage_ms: dict[str, float] = field(default_factory=dict)    # GPU time per stage (timestamp queries)
    seconds: float = 0.0                                # this frame's share of the run: from its recording,
                                                        # or the previous frame's hand-over where frames
                                                        # overlap, to its readback (they sum to the wall time)
    setup_seconds: float = 0.0                          # scene, BVH, kernels, networks (first frame only)
    samples: int = 0                                    # pixel samples taken (planned, for adaptive)

    @property
    def samples_per_second(self) -> float:
        return self.samples / self.seconds if self.seconds > 0 else 0.0


class StageTimer:
    """Timestamp marks between stages, resolved into the tail of the frame's readback buffer."""

    def __init__(self, ctx, capacity: int = 16):
        self.ctx, self.capacity = ctx, capacity
        self.query_set = ctx.device.create_query_set(type="timestamp", count=capacity)
        self.resolved = ctx.device.create_buffer(
            size=8 * capacity, usage=wgpu.BufferUsage.QUERY_RESOLVE | wgpu.BufferUsage.COPY_SRC)
        self.names: list[str] = []

    def start(self) -> None:
        self.names = []

    def mark(self, encoder, name: str) -> None:
        """The end of stage ``name`` (the first mark is the frame's start)."""
        if len(self.names) == self.capacity:
            raise ValueError(f"more than {self.capacity} timestamp marks in one frame")
        compute_pass = encoder.begin_compute_pass(
            label=f"mark {name}", timestamp_writes={"query_set": self.query_set,
                                                    "beginning_of_pass_write_index": len(self.names)})
        compute_pass.end()
        self.names.append(name)

    def resolve(self, encoder, destination, offset: int) -> None:
        encoder.resolve_query_set(self.query_set, 0, len(self.names), self.resolved, 0)
        encoder.copy_buffer_to_buffer(self.resolved, 0, destination, offset, 8 * len(self.names))

    def stage_ms(self, names: list[str], raw: bytes) -> dict[str, float]:
        ticks = np.frombuffer(raw, np.uint64, count=len(names)).astype(np.float64)
        return {name: (ticks[i] - ticks[i - 1]) / 1e6 for i, name in enumerate(names) if i}


def check_wiring(stages, written=()) -> None:
    """Every plane a stage declares as an input must be written by an earlier one (or be in ``written``,
    the tracer's planes): FrameBuffers would hand a plane nobody writes over as zeros, silently. Passes
    connect by these declarations; this makes a wrong connection an error when the pipeline is built."""
    available = {plane.name for plane in written}
    for stage in stages:
        missing = [plane.name for plane in stage.inputs if plane.name not in available]
        if missing:
            name = getattr(stage, "name", type(stage).__name__)
            raise ValueError(f"frame pipeline: {name} reads {', '.join(missing)}, which no earlier stage writes")
        available |= {plane.name for plane in stage.outputs}


def check_readback(hdr: bool, operator: str | None, aovs) -> None:
    """A frame must read something back: the HDR colour, the display image (a tone-map operator) or an
    AOV."""
    if not isinstance(hdr, bool):
        raise WgpuRtError(f"hdr must be True or False, got {hdr!r}")
    if not hdr and operator is None and not aovs:
        raise WgpuRtError("hdr=False with no display image (tonemap) and no AOVs: the frame would read "
                          "nothing back; ask for a display image, an AOV or the HDR colour")


@dataclass
class ReadbackLayout:
    """Where each plane read back sits in the frame's one readback buffer (byte offsets)."""

    planes: dict[str, tuple[PlaneSpec, int]]
    display_offset: int
    timestamps_offset: int
    nbytes: int


@dataclass
class PendingFrame:
    """A frame recorded (``commands``, until it is submitted) whose results ``readback`` will hold."""

    frame: int
    readback: object
    stage_names: list[str]
    started: float
    commands: object = None


class ProgressWaits:
    """Tells ``progress`` (a callable taking a sample count, or None: then nothing waits) how many samples
    per pixel of a long frame are done. Knowing that means waiting for the device, which then idles
    until the next submit, so it waits only every few submits: as many as take about PROGRESS_SECONDS,
    judged by the previous waits (the first submit is waited for alone)."""

    def __init__(self, ctx, buffers, progress):
        self.ctx, self.buffers, self.progress = ctx, buffers, progress
        self.unwaited, self.submits, self.stride = 0, 0, 1
        self.since = time.perf_counter()

    def submitted(self, samples: int) -> None:
        if self.progress is None:
            return
        self.unwaited += samples
        self.submits += 1
        if self.submits < self.stride:
            return
        self.ctx.read(self.buffers.get(SPP), np.uint32, nbytes=4)   # waits for everything submitted
        now = time.perf_counter()
        per_submit = (now - self.since) / self.submits
        self.stride = max(1, min(64, int(PROGRESS_SECONDS / max(per_submit, 1e-6))))
        self.progress(self.unwaited)
        self.unwaited, self.submits, self.since = 0, 0, now


class FramePipeline:
    """Everything between a scene and its rendered frames, for one size and one set of settings.

    ``trace_factory(frame, seed_frame)`` returns the tracer pass for that frame (a
    ``wgpu_rt.trace.TracePass``: ``clear`` and ``execute(encoder, buffers, schedule)``), its samples seeded
    as ``seed_frame``'s: the frame itself, or under a converging static view the first frame of the run,
    so the accumulated samples are one unbroken stratified sequence (at 8 spp on cornell, 96², re-seeding
    every frame left the mean 1.7 dB PSNR behind a brute-force 8-spp render: independent 1-spp sets lose
    the Sobol prefix's stratification).

    ``spp`` samples per pixel are traced per frame (in several submits when they are many; ``progress``,
    where given, is told every few, see ProgressWaits); ``adaptive`` replaces them by a 1-spp probe plus
    targeted samples. With ``aux_samples``, the albedo plane is then re-estimated noise-free from that
    many delta-chain paths per pixel (``TracePass.execute_aux``); without it, the tracer's albedo of the
    frame's own point samples is smoothed for the denoiser (frame/area_albedo.py), an albedo AOV staying the
    tracer's. ``low_band``: the denoiser's low band from passes at half (and quarter) resolution
    (frame/lowband.py; None: on frames whose sides reach LOW_BAND_MIN_SIDE while some pixel holds fewer than
    LOW_BAND_MAX_SPP samples). ``chroma``: the denoised colour balance held to the samples' block means
    (frame/chroma.py). ``post_filter``: the denoised frame smoothed by an edge-aware à-trous filter
    (frame/atrous.py). ``white_balance``: the denoiser's input white-balanced by the frame's gains
    (frame/pack.py); ``auto_exposure``: and brought to one key (None: as the denoiser was trained).
    ``aovs`` names the G-buffer planes to read back with the colour; ``operator`` None skips the display
    image; ``hdr=False`` skips the HDR colour (12 bytes a pixel; ``RenderResult.color`` is then None) for
    callers that want only the display image or AOVs.
    """

    def __init__(self, ctx, width: int, height: int, trace_factory, *, spp: int = 1, denoiser=None,
                 adaptive: AdaptiveSettings | None = None, error_predictor=None,
                 temporal: TemporalSettings | None = None, confidence=None, aovs=(),
                 operator: str | None = "aces", exposure: float = 0.0, srgb: bool = True,
                 output: str = "rgba8", timings: bool | None = None, progress=None, aux_samples: int = 0,
                 hdr: bool = True, low_band: bool | None = None, chroma: bool = True, post_filter: bool = True,
                 white_balance: bool = True, auto_exposure: bool | None = None):
        check_readback(hdr, operator, aovs)
        if adaptive is not None and adaptive.sampler == "heat" and error_predictor is None:
            raise ModelError("the heat adaptive sampler needs an error predictor model")
        self.ctx, self.width, self.height = ctx, width, height
        self.trace_factory, self.denoiser, self.error_predictor = trace_factory, denoiser, error_predictor
        self.spp, self.adaptive, self.progress, self.aux_samples = spp, adaptive, progress, aux_samples
        self.buffers = FrameBuffers(ctx, width, height)
        self.depth_max = DepthMaxPass(ctx, width, height)
        color, self.chain, self.low_band_setting = RADIANCE, None, low_band
        if denoiser is not None:
            # The low band: built when some frame may take it (a single frame of many samples never
            # does); each frame then asks again with the samples every pixel is sure to hold
            # (``_runs_low_band``). A frame of several samples per pixel (uniform or an adaptive map) hands
            # over from the denoiser to their mean where that has converged (frame/converge.py); temporal
            # mode does that itself across frames (its converge step).
            fewest = spp if temporal is None and adaptive is None else 1
            self.chain = DenoiseChain(ctx, width, height, denoiser, self.depth_max.result,
                                      low_band_levels(width, height, low_band, fewest), chroma, post_filter,
                                      converge=(spp > 1 or adaptive is not None) and temporal is None,
                                      white_balance=white_balance,
                                      auto_exposure=reads_at_one_key(denoiser, auto_exposure))
            color = self.chain.output
        # Without the aux pass the tracer's albedo is a few point samples a pixel: smoothed for the denoiser.
        self.area_albedo = AreaAlbedoPass(ctx, width, height) if denoiser is not None and not aux_samples else None
        half_aovs = {HALF_RADIANCE.name, HALF_SPP.name} & set(aovs)
        if half_aovs and temporal is not None:
            raise WgpuRtError(f"AOV {sorted(half_aovs)[0]!r} is the mean after the first half of one frame's samples; "
                              "temporal mode keeps its own copy across frames: leave it out")
        self.copies_half = self.chain is not None and self.chain.converge is not None or bool(half_aovs)
        self.temporal = None
        if temporal is not None:
            self.temporal = TemporalPass(ctx, width, height, color, temporal, confidence, self.depth_max.result,
                                         auto_exposure)
            color = TEMPORAL
        if adaptive is not None:
            source = SAMPLE_ERROR if adaptive.sampler == "variance" else HEAT
            self.extra_samples = ExtraSamplesPass(ctx, width, height, adaptive, source)
            # An error predictor trained with the exposure step reads its probe at one key (as the denoiser does).
            self.probe_exposure = (RadianceExposurePass(ctx, width, height) if adaptive.sampler == "heat"
                                   and reads_at_one_key(error_predictor, auto_exposure) else None)
            self.pack_error = PackErrorPass(ctx, width, height, getattr(self.probe_exposure, "result", None))
            self.half_buffer_error = HalfBufferErrorPass(ctx, width, height)
        self.color, self.hdr = color, hdr
        self.color_is_an_aov = color.name in aovs   # (the radiance AOV of a frame nothing denoises)
        self.tonemap = (TonemapPass(ctx, width, height, color, operator, exposure, srgb, output)
                        if operator is not None else None)
        check_wiring(self._stages(), written=TracePass.outputs)
        self.timer = StageTimer(ctx) if (ctx.has_timestamps if timings is None else timings) else None
        read_back = list(dict.fromkeys(([color] if hdr else []) + [AOV_PLANES[name] for name in aovs]))
        self.layout = self._layout(read_back)
        self.interleave = {plane.name: InterleavePass(ctx, width, height, plane)
                           for plane in read_back if interleaves(plane)}
        self._readbacks = [ctx.device.create_buffer(size=self.layout.nbytes, label=f"readback {i}",
                                                    usage=wgpu.BufferUsage.COPY_DST | wgpu.BufferUsage.MAP_READ)
                           for i in range(2)]
        self._recorded = 0
        self.previous_frame: int | None = None
        self.handed_over = 0.0   # when the last frame was read back (perf_counter)
        self.seed_frame = 0
        # Under a static camera (temporal mode) the planes accumulate: samples per pixel they hold, and
        # how many the converge pass's copy of them holds (it is taken again once the samples since the
        # copy reach those before it, so the copy holds a quarter to a half of them).
        self.accumulated = self.half_copied = 0
        self._aux_kept = None   # a static view's aux albedo (_aux_albedo)

    def prepare(self, frame: int) -> None:
        """Build what the first frame would build on its way: the tracer pass of ``frame`` (BVH, uploads,
        kernels) and each network's plan, kernels and bind groups at this size, so that a frame's
        ``seconds`` count its own work, as a peer's timed render leaves its scene load out."""
        self.trace_factory(frame, frame)
        if self.chain is not None:
            self.chain.prepare(self.buffers)
        if self.adaptive is not None and self.adaptive.sampler == "heat":
            prepare_network(self.error_predictor, self.buffers.get(ERROR_INPUT), self.height, self.width)
        if self.temporal is not None:
            self.temporal.prepare(self.buffers)

    def _stages(self) -> list:
        """What a frame runs after the tracer, in order, each with the planes it declares it reads and
        writes (networks and the pipeline's own copies included), for ``check_wiring``."""
        stages = [self.depth_max]
        if self.copies_half or (self.temporal is not None and self.temporal.converge is not None):
            stages.append(Stage("copy of part of the samples' mean", (RADIANCE, SPP), (HALF_RADIANCE, HALF_SPP)))
        if self.adaptive is not None:
            if self.adaptive.sampler == "variance":
                stages += [Stage("copy of the first probe sample", (RADIANCE,), (HALF_RADIANCE,)),
                           self.half_buffer_error]
            elif self.adaptive.sampler == "heat":
                stages += [stage for stage in (self.probe_exposure, self.pack_error) if stage is not None]
                stages.append(Stage("error predictor", (ERROR_INPUT,), (HEAT,)))
            stages.append(self.extra_samples)
        if self.area_albedo is not None:
            stages.append(self.area_albedo)
        if self.chain is not None:
            stages += self.chain.stages()
        return stages + [stage for stage in (self.temporal, self.tonemap) if stage is not None]

    def _aux_albedo(self, encoder, trace, converging: bool) -> None:
        """The noise-free albedo plane. A converging static view (temporal mode) keeps its first frame's
        seed, camera and scene, so its aux estimate would come out the same every frame: it is traced on
        the view's first frame and kept in a copy, which later frames put back (the tracer folds its own
        noisy albedo samples into the plane each frame)."""
        albedo = self.buffers.get(ALBEDO)
        if self.temporal is None:
            trace.execute_aux(encoder, self.buffers, self.aux_samples)
        elif converging and self._aux_kept is not None:
            encoder.copy_buffer_to_buffer(self._aux_kept, 0, albedo, 0, albedo.size)
        else:
            trace.execute_aux(encoder, self.buffers, self.aux_samples)
            if self._aux_kept is None:
                self._aux_kept = self.ctx.storage(albedo.size, label="aux albedo, kept")
            encoder.copy_buffer_to_buffer(albedo, 0, self._aux_kept, 0, albedo.size)

    def _runs_low_band(self) -> bool:
        """Whether this frame's denoiser takes the low band: the samples every pixel is sure to hold are
        those accumulated so far (uniform ones; an adaptive frame's probes, not its targeted samples)."""
        return self.chain.low_band is not None and uses_low_band(self.width, self.height, self.low_band_setting,
                                                                 self.accumulated)

    def _layout(self, planes: list[PlaneSpec]) -> ReadbackLayout:
        offsets, offset = {}, 0
        for plane in planes:
            offsets[plane.name] = (plane, offset)
            offset += plane.nbytes(self.width, self.height)
        display_offset = offset
        if self.tonemap is not None:
            offset += self.tonemap.display.nbytes(self.width, self.height)
        timestamps_offset = offset
        if self.timer is not None:
            offset += 8 * self.timer.capacity
        return ReadbackLayout(offsets, display_offset, timestamps_offset, offset)

    def _mark(self, encoder, name: str) -> None:
        if self.timer:
            self.timer.mark(encoder, name)

    def _uniform_batches(self, trace, samples: int) -> list[int]:
        """``samples`` split into batches of at most one submit's worth (whole dispatches of the trace's
        chunks)."""
        per_submit = self._samples_per_submit(trace)
        return [min(per_submit, samples - done) for done in range(0, samples, per_submit)]

    def _samples_per_submit(self, trace) -> int:
        """Samples per pixel one command buffer holds at most (SAMPLES_PER_SUBMIT pixel samples, whole chunks)."""
        chunk = trace.chunk_size
        return max(chunk, SAMPLES_PER_SUBMIT // (self.width * self.height) // chunk * chunk)

    def _trace(self, encoder, trace, keep_samples: bool):
        """Record this frame's samples, submitting a command buffer whenever the next batch would take it
        past one submit's worth (so a frame of few samples is one command buffer, its stage times free of
        host gaps); with ``keep_samples`` they join the previous frames' in the planes (the tracer numbers
        them after each pixel's spp, so the planes stay unbiased running means). Returns the encoder to
        go on."""
        buffers, adaptive = self.buffers, self.adaptive
        if not keep_samples:
            trace.clear(encoder, buffers)
        if adaptive is None:
            # A converging frame copies its mean after the first half of its samples (None below).
            first = half_count(self.spp) if self.copies_half else self.spp
            steps = self._uniform_batches(trace, first)
            if first < self.spp:
                steps += [None, *self._uniform_batches(trace, self.spp - first)]
            per_submit, recorded = self._samples_per_submit(trace), 0
            waits = ProgressWaits(self.ctx, buffers, self.progress)
            for step in steps:
                if step is None:
                    copy_half(encoder, buffers)
                    continue
                if recorded and recorded + step > per_submit:
                    self.ctx.device.queue.submit([encoder.finish()])
                    waits.submitted(recorded)
                    encoder, recorded = self.ctx.device.create_command_encoder(label="trace batch"), 0
                trace.execute(encoder, buffers, SampleSchedule(samples=step))
                recorded += step
            self._mark(encoder, "trace")
            return encoder
        if adaptive.sampler == "variance":
            trace.execute(encoder, buffers, SampleSchedule(samples=1))
            encoder.copy_buffer_to_buffer(buffers.get(RADIANCE), 0, buffers.get(HALF_RADIANCE), 0,
                                          RADIANCE.nbytes(self.width, self.height))
            trace.execute(encoder, buffers, SampleSchedule(samples=1))   # numbered after the first (spp = 1)
            self._mark(encoder, "probe")
            self.half_buffer_error.execute(encoder, buffers)
        else:
            trace.execute(encoder, buffers, SampleSchedule(samples=1))
            self._mark(encoder, "probe")
            if adaptive.sampler == "heat":
                if self.probe_exposure is not None:
                    self.probe_exposure.execute(encoder, buffers)
                self.pack_error.execute(encoder, buffers)
                heat = self.error_predictor.record(encoder, buffers.get(ERROR_INPUT), self.height, self.width)
                encoder.copy_buffer_to_buffer(heat, 0, buffers.get(HEAT), 0, HEAT.nbytes(self.width, self.height))
        if self.copies_half:   # the probe is the part the converge pass measures the mean's error by
            copy_half(encoder, buffers)
        self.extra_samples.execute(encoder, buffers)
        self._mark(encoder, "sample map")
        # No sample_offset: the tracer already numbers these after the probe's (each pixel's spp), so
        # probe and targeted samples are one unbroken prefix of the pixel's sequence, as brute force is.
        # The pass compacts the map on the device, so its cost follows the samples, not the image.
        trace.execute(encoder, buffers, SampleSchedule(
            samples=adaptive.max_extra, sample_counts=buffers.get(self.extra_samples.outputs[0]),
            total_samples=adaptive.extra_bound(self.width * self.height)))
        self._mark(encoder, "targeted trace")
        return encoder

    def record(self, scene, frame: int) -> PendingFrame:
        """Record one frame (a large ``spp`` submits its first sample batches as it goes); ``submit``
        sends the rest, ``finish`` reads it back. At most two frames may be pending."""
        ctx, buffers = self.ctx, self.buffers
        started = time.perf_counter()
        # Temporal mode under a static camera and scene converges in the tracer: the frame adds its
        # samples to the running mean, which is denoised and then replaces the temporal history
        # (averaging denoised 1-spp frames would keep the denoiser's bias). Any change or cut starts
        # again from zero samples.
        change = frame_change(scene, self.previous_frame, frame) if self.temporal is not None else "cut"
        converging = change == "static"
        if not converging:
            self.seed_frame = frame
        trace = self.trace_factory(frame, self.seed_frame)
        encoder = ctx.device.create_command_encoder(label=f"frame {frame}")
        if self.timer:
            self.timer.start()
        self._mark(encoder, "start")
        if not converging:
            self.accumulated = self.half_copied = 0
        elif self.temporal.converge is not None and self.accumulated >= 2 * self.half_copied:
            copy_half(encoder, self.buffers)
            self.half_copied = self.accumulated
        encoder = self._trace(encoder, trace, keep_samples=converging)
        self.accumulated += self.spp
        if self.aux_samples:
            self._aux_albedo(encoder, trace, converging)
            self._mark(encoder, "aux")
        elif self.area_albedo is not None:
            self.area_albedo.execute(encoder, buffers)
            self._mark(encoder, "area albedo")
        self.depth_max.execute(encoder, buffers)
        if self.chain is not None:
            self.chain.record(encoder, buffers, low_band=self._runs_low_band(), mark=self._mark)
        if self.area_albedo is not None:
            self.area_albedo.restore(encoder, buffers)
        if self.temporal is not None:
            self.temporal.execute(encoder, buffers, "converge" if converging else change)
            self._mark(encoder, "temporal")
        if self.tonemap is not None:
            self.tonemap.execute(encoder, buffers)
            self._mark(encoder, "tonemap")
        readback = self._readbacks[self._recorded % 2]
        for interleave in self.interleave.values():
            interleave.execute(encoder, buffers)
        if self.interleave:
            self._mark(encoder, "interleave")
        for plane, offset in self.layout.planes.values():
            source = self.interleave[plane.name].result if plane.name in self.interleave else buffers.get(plane)
            encoder.copy_buffer_to_buffer(source, 0, readback, offset, plane.nbytes(self.width, self.height))
        if self.tonemap is not None:
            encoder.copy_buffer_to_buffer(buffers.get(self.tonemap.display), 0, readback, self.layout.display_offset,
                                          self.tonemap.display.nbytes(self.width, self.height))
        if self.timer:
            self.timer.resolve(encoder, readback, self.layout.timestamps_offset)
        self._recorded += 1
        self.previous_frame = frame
        return PendingFrame(frame, readback, list(self.timer.names) if self.timer else [], started, encoder.finish())

    def submit(self, pending: PendingFrame) -> PendingFrame:
        """Send a recorded frame to the device."""
        self.ctx.device.queue.submit([pending.commands])
        pending.commands = None
        return pending

    @staticmethod
    def wait(pending: PendingFrame) -> None:
        """Block until a submitted frame is done (and everything submitted after it: see the module's
        docstring) and its readback buffer is mapped."""
        pending.readback.map_sync(wgpu.MapMode.READ)

    def finish(self, pending: PendingFrame) -> RenderResult:
        """Wait for a submitted frame and read it back."""
        self.wait(pending)
        return self.read(pending)

    def read(self, pending: PendingFrame) -> RenderResult:
        """A frame whose readback ``wait`` mapped: each plane copied once from the mapped memory into the
        (H, W, C) array returned (a 1080p HDR frame is 25 MB, and the host's copies are what a frame
        costs beyond its GPU time: f32 planes of several channels arrive interleaved by the device, so
        theirs is one contiguous copy), then the buffer unmapped."""
        try:
            raw = pending.readback.read_mapped(copy=False)   # valid until unmap: nothing below keeps it
            planes = {}
            for name, (plane, offset) in self.layout.planes.items():
                values = np.frombuffer(raw, NUMPY_DTYPE[plane.dtype], count=plane.channels * self.height * self.width,
                                       offset=offset)
                planes[name] = (values.reshape(self.height, self.width, plane.channels).copy()
                                if name in self.interleave else interleaved(values, self.height, self.width))
            image = None
            if self.tonemap is not None:
                image = self.tonemap.image(raw[self.layout.display_offset:self.layout.timestamps_offset],
                                           self.width, self.height)
            stage_ms = (self.timer.stage_ms(pending.stage_names, raw[self.layout.timestamps_offset:])
                        if self.timer else {})
        finally:
            pending.readback.unmap()
        color = None
        if self.hdr:
            color = planes[self.color.name].copy() if self.color_is_an_aov else planes.pop(self.color.name)
        mean_spp = self.spp if self.adaptive is None else (self.adaptive.budget or self.adaptive.probe_samples)
        samples = mean_spp * self.width * self.height
        # A frame recorded while the one before it ran counts from that one's hand-over, so that frames in
        # flight do not count the same seconds twice.
        started, self.handed_over = max(pending.started, self.handed_over), time.perf_counter()
        return RenderResult(pending.frame, color, planes, image, stage_ms, self.handed_over - started,
                            samples=int(round(samples)))

    def render(self, scene, frame: int) -> RenderResult:
        """Record, submit and read back one frame."""
        return self.finish(self.submit(self.record(scene, frame)))

    def frames(self, scene, frames):
        """Render ``frames`` in order: frame N+1 recorded while frame N runs, and running while frame N
        is copied out and handed to the caller."""
        pending = None
        for frame in frames:
            recorded = self.record(scene, frame)
            if pending is not None:
                self.wait(pending)
            self.submit(recorded)
            if pending is not None:
                yield self.read(pending)
            pending = recorded
        if pending is not None:
            yield self.finish(pending)
