"""``render()``: the front door. One call path traces a scene and, when asked, denoises, samples
adaptively, accumulates over time and tone-maps, on the device, returning numpy arrays.

    result = wgpu_rt.render("cornell", spp=1, size=(256, 256), denoise=True, adaptive=4)
    result.color        # (H, W, 3) float32 linear HDR (None with hdr=False)
    result.aovs         # albedo, normal, depth, motion, spp: (H, W, C) float32
    result.image        # display image when ``tonemap`` names an operator

``frames`` renders several frames with the scene set up once (BVH, kernels, networks) and one frame in
flight while the previous one is read back. Every argument is checked before any work starts; a bad one
is a ``WgpuRtError`` naming it. The command line (``wgpu-rt render``) is a shell over this call.
"""

from __future__ import annotations

import numbers
import sys
import time
from typing import Iterable, Iterator

from .errors import WgpuRtError
from .frame.pipeline import AOV_PLANES, FramePipeline, RenderResult, check_readback
from .trace.trace_pass import AUX_SAMPLES

DEFAULT_AOVS = ("albedo", "normal", "depth", "motion", "spp")
# A still scene that places shapes several times traces through two levels only when its placed
# triangles exceed this; below it, copying them costs little memory and BVH build (80k: 11.5 MiB,
# 0.6 s on lavapipe) and a single level traces up to 1.27× faster (BENCHMARKS.md §6, "Instancing").
FLATTEN_PLACED_TRIANGLES = 100_000
# as wgpu_rt.nn.model.PRECISION_CHOICES (not imported here: the NN engine loads only with a network)
PRECISION_CHOICES = ("auto", "fp32", "fp16")
MAX_SIZE = 16384

__all__ = ["DEFAULT_AOVS", "RenderResult", "Renderer", "denoise", "render", "render_frames"]


def parse_size(size) -> tuple[int, int]:
    """(width, height) from a pair or "WxH"."""
    if isinstance(size, str):
        try:
            width, height = (int(v) for v in size.lower().split("x"))
        except ValueError:
            raise WgpuRtError(f"size {size!r}: expected WIDTHxHEIGHT, e.g. 256x256") from None
    else:
        try:
            width, height = size
        except (TypeError, ValueError):
            raise WgpuRtError(f"size {size!r}: expected (width, height)") from None
    if not all(_is_int(v) for v in (width, height)) or not (1 <= width <= MAX_SIZE and 1 <= height <= MAX_SIZE):
        raise WgpuRtError(f"size {width}x{height}: width and height must be integers in 1..{MAX_SIZE}")
    return int(width), int(height)


def check_aovs(aovs) -> tuple[str, ...]:
    if isinstance(aovs, str):
        aovs = [a.strip() for a in aovs.split(",") if a.strip()]
    unknown = [a for a in aovs if a not in AOV_PLANES]
    if unknown:
        raise WgpuRtError(f"unknown AOV {unknown[0]!r}; choose from {', '.join(AOV_PLANES)}")
    return tuple(dict.fromkeys(aovs))


def _is_int(value) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def check_int(name: str, value, low: int, high: int | None = None) -> int:
    if not _is_int(value) or value < low or (high is not None and value > high):
        bound = f"in {low}..{high}" if high is not None else f"at least {low}"
        raise WgpuRtError(f"{name} must be an integer {bound}, got {value!r}")
    return int(value)


def check_denoiser_settings(width: int, height: int, precision: str, quality: str, low_band, chroma, post_filter,
                            white_balance, auto_exposure) -> None:
    """A WgpuRtError naming the first of the denoiser's settings (``render``'s and ``denoise``'s) that is bad."""
    from .frame.denoise import QUALITIES
    from .frame.lowband import uses_low_band

    if precision not in PRECISION_CHOICES:
        raise WgpuRtError(f"precision {precision!r}: choose one of {', '.join(PRECISION_CHOICES)}")
    if quality not in QUALITIES:
        raise WgpuRtError(f"quality {quality!r}: choose one of {', '.join(QUALITIES)}")
    uses_low_band(width, height, low_band)   # checks the setting
    for name, value in (("chroma", chroma), ("post_filter", post_filter), ("white_balance", white_balance)):
        if not isinstance(value, bool):
            raise WgpuRtError(f"{name} must be True or False, got {value!r}")
    if auto_exposure is not None and not isinstance(auto_exposure, bool):
        raise WgpuRtError(f"auto_exposure must be True, False or None, got {auto_exposure!r}")


def _frame_list(frames, frame_count: int, animated: bool) -> list[int]:
    """The frames asked for; an animated scene has ``frame_count`` frames, a static one any number
    (static frames are identical views, e.g. for temporal accumulation)."""
    if frames is None:
        listed = [0]
    elif _is_int(frames):
        listed = [frames]
    else:
        try:
            listed = list(frames)
        except TypeError:
            raise WgpuRtError(f"frames must be a frame number or an iterable of them, got {frames!r}") from None
    if not listed:
        raise WgpuRtError("frames is empty")
    for frame in listed:
        check_int("a frame number", frame, 0, 2 ** 31 - 1)
    beyond = [f for f in listed if f >= frame_count]
    if animated and beyond:
        raise WgpuRtError(f"frame {beyond[0]} is beyond the scene's {frame_count} frames (0..{frame_count - 1})")
    return listed


class Renderer:
    """A scene set up once for one size and one set of settings (what ``render`` builds; keep one to
    render frames one at a time, e.g. to time the steady state after the first)."""

    def __init__(self, scene, spp: int = 1, size=(256, 256), *, denoise: bool = False, adaptive=None,
                 temporal=False, max_depth: int = 8, seed: int = 0, aovs=DEFAULT_AOVS, tonemap: str | None = None,
                 exposure: float = 0.0, srgb: bool = True, display: str = "rgba8", precision: str = "auto",
                 models_dir=None, networks: dict | None = None, mesh=None, camera: str | None = None,
                 animation: str | None = None, ctx=None,
                 progress: bool = False,
                 timings: bool | None = None, aux_samples: int | None = None, hdr: bool = True,
                 quality: str = "balanced", low_band: bool | None = None, chroma: bool = True,
                 post_filter: bool = True, white_balance: bool = True, auto_exposure: bool | None = None):
        from .frame.adaptive import AdaptiveSettings
        from .frame.temporal import TemporalSettings
        from .frame.tonemap import check_settings

        started = time.perf_counter()
        self.width, self.height = parse_size(size)
        self.spp = check_int("spp", spp, 1)
        self.max_depth = check_int("max_depth", max_depth, 1)
        self.seed = check_int("seed", seed, 0, 2 ** 32 - 1)
        self.aovs = check_aovs(aovs)
        # The denoiser gets a noise-free albedo by default (OIDN's advice for auxiliary features).
        aux_samples = (AUX_SAMPLES if denoise else 0) if aux_samples is None else check_int("aux_samples", aux_samples, 0)
        check_denoiser_settings(self.width, self.height, precision, quality, low_band, chroma, post_filter,
                                white_balance, auto_exposure)
        if tonemap is not None:
            check_settings(tonemap, display, exposure)
        check_readback(hdr, tonemap, self.aovs)
        if adaptive is not None and not isinstance(adaptive, AdaptiveSettings):
            if not isinstance(adaptive, numbers.Real) or isinstance(adaptive, bool) or adaptive != adaptive:
                raise WgpuRtError(f"adaptive must be a mean spp budget, got {adaptive!r}")
            adaptive = AdaptiveSettings(budget=float(adaptive))
        if adaptive is not None and self.spp != 1:
            raise WgpuRtError(f"spp {self.spp} with adaptive sampling: the adaptive budget sets the samples "
                              "(mean spp); leave spp at 1")
        temporal = TemporalSettings() if temporal is True else (temporal or None)
        self.progress = progress

        from .frame.denoise import load_model
        from .gpu import get_context
        from .scene import load_scene

        self.scene = load_scene(scene, mesh=mesh, camera=camera, animation=animation)
        self.ctx = ctx or get_context()
        networks = dict(networks or {})
        if denoise and "denoiser" not in networks:
            networks["denoiser"] = load_model("denoiser", precision, models_dir, ctx=self.ctx, quality=quality)
        if adaptive is not None and adaptive.sampler == "heat" and "error_predictor" not in networks:
            networks["error_predictor"] = load_model("error_predictor", precision, models_dir, ctx=self.ctx)
        if temporal is not None and "confidence" not in networks:
            networks["confidence"] = load_model("confidence", precision, models_dir, ctx=self.ctx, required=False)
        self._bar = None
        self.pipeline = FramePipeline(
            self.ctx, self.width, self.height, self._trace_factory(), spp=self.spp,
            denoiser=networks.get("denoiser") if denoise else None, adaptive=adaptive,
            error_predictor=networks.get("error_predictor"), temporal=temporal,
            confidence=networks.get("confidence"), aovs=self.aovs, operator=tonemap, exposure=exposure,
            srgb=srgb, output=display, timings=timings, aux_samples=aux_samples, hdr=hdr,
            low_band=low_band, chroma=chroma, post_filter=post_filter, white_balance=white_balance,
            auto_exposure=auto_exposure)
        self.setup_seconds = time.perf_counter() - started

    def _trace_factory(self):
        """Tracer passes by geometry: a frame whose objects did not move reuses the pass (and its BVH),
        with only the camera and seed changed. When objects move, the new pass holds a two-level
        geometry (InstancedGeometry: each mesh's BVH built once) that later frames move in place, moving
        emissive meshes' entries of the emitter table with them; a pass's first frame keeps the
        single-level BVH, which traces faster, so a single frame never pays for levels. A scene that
        places a shape several times (instances) gets the two-level geometry from its first frame on,
        which stores each shape's triangles once, unless it places at most FLATTEN_PLACED_TRIANGLES.
        Frame f is seeded seed + f (mod 2³²)."""
        from .accel.geometry import GeometryBuffers, InstancedGeometry, bvh_layout, split_variant, traversal_module
        from .trace.bvh_choice import AUTO_MIN_TRIANGLES, choose_layout, remembers_small_leaves, unmeasured_layout
        from .trace.trace_pass import TracePass

        traced: dict[bytes, TracePass] = {}   # by the frame's transforms, or follows_every_frame
        follows_every_frame = b"instanced"
        scene = self.scene
        can_instance = InstancedGeometry.suits(scene)
        placed_triangles = sum(len(mesh.faces) for mesh in scene.meshes)
        instanced_from_start = can_instance and scene.has_instances and placed_triangles > FLATTEN_PLACED_TRIANGLES
        layout = bvh_layout()
        # Two-level scenes are not measured (their BVHs change with the frames). Their bottom levels take
        # the variant measured for the scene's single-level first frame where there was one (a mesh that
        # starts to move keeps the walk it was traced with standing still), else the adapter's pick.
        instanced_variant = [unmeasured_layout(self.ctx, traversal_module(self.ctx)) if layout == "auto" else layout]

        def trace_for(frame: int, seed_frame: int):
            seed = (self.seed + seed_frame) % 2 ** 32
            # (a bending mesh's geometry holds where its vertices were at the frame before too)
            key = b"".join(m.pose_key(frame) + (m.pose_key(frame - 1) if m.deforms else b"") for m in scene.meshes)
            trace = traced.get(follows_every_frame) or traced.get(key)
            if trace is None:   # objects moved: new BVH, new uploads (the last time, when instanced)
                moved = bool(traced)
                traced.clear()
                if instanced_from_start or (moved and can_instance):
                    variant = instanced_variant[0]
                    geometry = InstancedGeometry(scene, frame, split_variant(variant)[1]).as_variant(variant)
                    key = follows_every_frame
                elif layout == "auto":
                    built = GeometryBuffers.build(scene, frame, remembers_small_leaves(self.ctx, scene))
                    geometry = choose_layout(self.ctx, scene, built, self.max_depth, frame)
                    if built.triangle_count >= AUTO_MIN_TRIANGLES:
                        instanced_variant[0] = geometry.variant
                else:
                    geometry = GeometryBuffers.build(scene, frame, split_variant(layout)[1]).as_variant(layout)
                trace = traced[key] = TracePass(self.ctx, scene, geometry, self.width, self.height, frame=frame,
                                                max_depth=self.max_depth, seed=seed)
            else:
                trace.set_frame(scene, frame, seed)
            return trace

        return trace_for

    def _advance(self, samples: int) -> None:
        self._bar.update(samples)

    def _progress_bar(self, total: int, unit: str):
        """A bar on a terminal only: piped into a log it would be noise, and counting samples makes a long
        frame wait for the device to report."""
        if not self.progress or not sys.stderr.isatty():
            return None
        from tqdm import tqdm

        return tqdm(total=total, unit=unit, desc=f"render {self.scene.name}", leave=False)

    def frames(self, frames=None) -> Iterator[RenderResult]:
        """Render ``frames`` (a frame number or an iterable; default frame 0) in order, the next frame
        running on the device while the caller holds this one; the first result carries the setup time
        (the renderer's, and what the first frame would build on its way: its BVH and the networks' plans
        are built here, before any frame's clock starts, as a peer's scene load is)."""
        listed = _frame_list(frames, self.scene.frame_count, self.scene.is_animated)
        started = time.perf_counter()
        self.pipeline.prepare(listed[0])   # the first frame's BVH, uploads and network plans: set-up
        setup_seconds = self.setup_seconds + time.perf_counter() - started
        single = len(listed) == 1
        self._bar = self._progress_bar(self.spp if single else len(listed), "spp" if single else "frame")
        # only a bar counting samples waits for the device mid-frame (see frame.pipeline.ProgressWaits)
        self.pipeline.progress = self._advance if self._bar is not None and single else None
        try:
            for index, result in enumerate(self.pipeline.frames(self.scene, listed)):
                if index == 0:
                    result.setup_seconds = setup_seconds
                if self._bar is not None and not single:
                    self._bar.update(1)
                yield result
        finally:
            if self._bar is not None:
                self._bar.close()
                self._bar = None


def render(scene, spp: int = 1, size=(256, 256), *, denoise: bool = False, adaptive=None, temporal=False,
           frames=None, **options) -> RenderResult | list[RenderResult]:
    """Render ``scene`` (a Scene, a built-in name or a scene-file path; ``mesh=`` for the built-in 'mesh').

    - ``spp``: samples per pixel per frame; ``size``: (width, height) or "WxH".
    - ``denoise``: run the denoiser (``models/denoiser.onnx``) on the device.
    - ``adaptive``: a mean-spp budget for error-predictor-guided sampling (a 1-spp probe, then targeted
      samples), or ``AdaptiveSettings``; replaces ``spp``.
    - ``temporal``: accumulate over ``frames`` (reprojection, history clamping, confidence network), True
      or ``TemporalSettings``. A static view keeps adding samples to one converging mean.
    - ``frames``: None (frame 0) or a frame number → one ``RenderResult``; an iterable → a list.
    - options: ``max_depth`` (8; Mitsuba's convention), ``seed`` (0; frame f is seeded seed + f),
      ``aovs`` (names or "a,b"), ``tonemap`` (None, "aces", "reinhard" or "none": the display image),
      ``exposure``, ``srgb``, ``display`` ("rgba8" or "f32"), ``precision`` ("fp32"/"fp16" networks, or
      "auto": fp16 on discrete GPUs with shader-f16),
      ``quality`` ("balanced", or "high": the denoiser averages 4 turned passes, 4× its work),
      ``low_band`` (the denoiser's band below quarter resolution from passes at half and, from 512² up,
      quarter resolution, 1.25–1.31× its work; None: on frames whose sides are all ≥ 256 while some
      pixel holds fewer than 16 samples, True, False),
      ``chroma`` (True: the denoised colour balance over 4×4-pixel blocks held to what the samples' own
      means there support; False: the network's as it comes), ``post_filter`` (True: the denoised frame
      smoothed by an edge-aware à-trous filter guided by albedo, normal and depth; False: not),
      ``white_balance`` (True: the network reads the irradiance divided per channel by the frame's gains,
      the square roots of its channels' means over their mean, and its output is multiplied back; False:
      as it is), ``auto_exposure`` (True: those gains also bring the frame's irradiance to one key, the
      log-average of its 8×8 tiles' means, so that the network reads the frame alike at any scale of its
      light, and the error predictor and confidence model read their radiance at a key of their own;
      False: every network at the scale the frame has; None: each as it was trained, its ONNX metadata),
      ``models_dir``, ``networks`` ({"denoiser": model, …} to use instead of loading), ``mesh``, ``camera`` (a glTF
      scene's camera by index or name), ``animation`` (which of a glTF file's animations plays), ``ctx``,
      ``progress`` (a progress bar, on a terminal), ``timings`` (per-stage GPU times; default: when the
      adapter has them),
      ``hdr`` (True: read back the linear HDR colour; False leaves ``color`` None and saves its 12 bytes a
      pixel of readback, for callers that need only ``image`` or the AOVs; one of the three is required).
    """
    renderer = Renderer(scene, spp, size, denoise=denoise, adaptive=adaptive, temporal=temporal, **options)
    results = list(renderer.frames(frames))
    return results if frames is not None and not _is_int(frames) else results[0]


def render_frames(scene, frames: Iterable[int] | None = None, **options) -> Iterator[RenderResult]:
    """``render`` as an iterator: each frame's result as soon as it is read back (default: every frame
    of the scene). Same options as ``render``."""
    renderer = Renderer(scene, **options)
    yield from renderer.frames(range(renderer.scene.frame_count) if frames is None else frames)


# The denoisers ``denoise`` has loaded, by (ONNX path, precision, quality, device id), each beside its device (an id
# can be reused once a context is gone): a second call builds nothing.
_DENOISERS: dict = {}


def denoise(color, albedo, normal, depth, spp=1, *, albedo_samples=None, half=None, model=None,
            precision: str = "auto", quality: str = "balanced", low_band: bool | None = None, chroma: bool = True,
            post_filter: bool = True, white_balance: bool = True, auto_exposure: bool | None = None,
            ctx=None):
    """Denoise images you already have (another renderer's, or ours read back): (H, W, 3) linear HDR ``color``
    of ``spp`` samples a pixel (a count, or an (H, W[, 1]) map) with its (H, W, 3) ``albedo``, (H, W, 3)
    ``normal`` and (H, W[, 1]) ``depth`` (0 where nothing was hit; None, for a renderer that writes OIDN's three
    inputs only, costs 0.2 dB on the mean, BENCHMARKS.md §46) → the denoised (H, W, 3) float32 colour,
    as `wgpu-rt denoise` gives for the same layers. On the device with the shipped denoiser, or ``model`` (an
    ONNX path); loaded once per model and settings.

    - ``albedo_samples``: point samples a pixel that the albedo averages (it is smoothed over each pixel's
      area first, as the network was trained on); 0 for an albedo already averaged so, as
      ``render(aux_samples=N)`` writes it; None: the colour's samples, as another renderer's albedo holds.
    - ``half``: (the mean after the first part of the samples, its (H, W) counts): each pixel then hands over
      to the samples' own mean where that has converged.
    - ``precision``, ``quality``, ``low_band``, ``chroma``, ``post_filter``, ``white_balance``,
      ``auto_exposure``: as for ``render``. NaN and Inf in the inputs count as 0.
    """
    import numpy as np

    from .frame.denoise import denoise_render, load_model
    from .gpu import get_context

    color = _finite_image("color", color, 3)
    height, width = color.shape[:2]
    albedo, normal = (_finite_image(name, image, 3, (height, width)) for name, image in (("albedo", albedo),
                                                                                      ("normal", normal)))
    depth = None if depth is None else _finite_image("depth", depth, 1, (height, width))
    check_denoiser_settings(width, height, precision, quality, low_band, chroma, post_filter, white_balance,
                            auto_exposure)
    spp = _sample_counts("spp", spp, (height, width))
    if albedo_samples is not None and not (isinstance(albedo_samples, numbers.Real) and albedo_samples >= 0):
        raise WgpuRtError(f"albedo_samples must be a number of samples ≥ 0 or None, got {albedo_samples!r}")
    if half is not None:
        try:
            mean, counts = half
        except (TypeError, ValueError):
            raise WgpuRtError("half must be (mean, counts): the colour after the first part of the samples "
                              "and how many it holds") from None
        counts = _sample_counts("half's counts", counts, (height, width))
        half = (_finite_image("half's mean", mean, 3, (height, width)),
                np.broadcast_to(np.reshape(counts, np.shape(counts)[:2]), (height, width)))
    ctx = ctx or get_context()
    key = (str(model), precision, quality, id(ctx))
    if key not in _DENOISERS or _DENOISERS[key][0] is not ctx:
        _DENOISERS[key] = ctx, load_model("denoiser", precision, path=model, ctx=ctx, quality=quality)
    return denoise_render(_DENOISERS[key][1], color, albedo, normal, depth, spp, albedo_samples, half=half,
                          low_band=low_band, chroma=chroma, post_filter=post_filter, white_balance=white_balance,
                          auto_exposure=auto_exposure)


def _finite_image(name: str, image, channels: int, shape: tuple[int, int] | None = None):
    """``image`` as a float32 (H, W, channels) array (a one-channel one may come as (H, W)), NaN and Inf as 0,
    of ``shape`` where given; else a WgpuRtError naming it."""
    import numpy as np

    try:
        array = np.asarray(image, dtype=np.float32)
    except (TypeError, ValueError):
        raise WgpuRtError(f"{name} must be an image (an array of numbers), got {type(image).__name__}") from None
    if array.ndim == 2 and channels == 1:
        array = array[..., None]
    if array.ndim != 3 or array.shape[2] != channels or min(array.shape[:2]) < 1:
        raise WgpuRtError(f"{name} must be (H, W, {channels}), got shape {array.shape}")
    if shape is not None and array.shape[:2] != shape:
        raise WgpuRtError(f"{name} is {array.shape[1]}×{array.shape[0]}, the colour {shape[1]}×{shape[0]}")
    return np.nan_to_num(array, nan=0.0, posinf=0.0, neginf=0.0)


def _sample_counts(name: str, spp, shape: tuple[int, int]):
    """A sample count ≥ 1, or an (H, W[, 1]) map of counts ≥ 0 (as an (H, W, 1) array); else a WgpuRtError."""
    import numpy as np

    if np.ndim(spp) == 0:
        if not isinstance(spp, numbers.Real) or isinstance(spp, bool) or not spp >= 1 or spp == float("inf"):
            raise WgpuRtError(f"{name} must be a sample count ≥ 1 or an (H, W) map of counts, got {spp!r}")
        return spp
    counts = np.asarray(spp, dtype=np.float64)
    counts = counts[..., None] if counts.ndim == 2 else counts
    if counts.shape != (*shape, 1) or not np.all(np.isfinite(counts)) or counts.min() < 0:
        raise WgpuRtError(f"{name} must be a sample count or an (H, W) map of finite counts ≥ 0 as large as "
                          f"the colour, got shape {counts.shape}")
    return counts
