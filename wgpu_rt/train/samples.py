"""Training samples for the three networks, built from a loaded dataset.

Inputs are packed by ``wgpu_rt.frame.pack``'s numpy references on the *full* frame (so the depth
normalisation sees the frame's true max depth, as at runtime), then, as torch tensors on the training
device, cropped and exposed (the crop alone, where the target is made pixel by pixel) and augmented:

- exposure jitter: colour and gold scaled by 2^U(−1, 1), applied to the packed log1p planes as
  log1p(e · expm1(p)), the same as packing the scaled render with the frame's own gains (the log1p
  compression makes this a non-trivial change of the input, which is the point); since the gains carry
  the frame's exposure (frame/pack.py), which packing the scaled render anew would take out again, it
  stands for the exposure step's key missing by up to a stop;
- a random square crop of ``crop`` ∈ [crop_min, crop_max] (a multiple of ``multiple``, at most the
  frame), the same for a whole batch, whose frames the trainer draws from one crop limit
  (``grouped_by_crop``: datasets of several frame sizes mix);
- one of the 8 flips/90° rotations;
- small Gaussian noise on the auxiliary channels (albedo, normal, depth), so the network does not
  trust G-buffers blindly;
- with ``permute_colours``, one random order of the R, G, B channels per crop, applied alike to every
  colour triple of input and target (colour, albedo): exact for an RGB renderer, whose light transport
  is the same per channel, so the network sees bounce light of every hue (the shipped one greys a room
  lit by a green wall: BENCHMARKS.md §17);
- where the dataset has ``noisy_copies``, a random one of the frame's independent 1-spp renders (a
  fresh noise realization, G-buffers included), so the network cannot learn a view's noise by heart;
- for the denoiser, a curriculum over sample counts: 16 spp first, then 4, then 1 (configurable); a
  stage of ``ANY_SPP`` lets each crop draw one of its view's rendered sample counts (uniformly), which
  is how the sample-count input plane learns what it means.
"""

from __future__ import annotations

import itertools
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from ..dataset.store import View
from ..frame.denoise_chain import INPUT_EXPOSURE
from ..frame.pack import (CONFIDENCE_KEY, albedo_factor, demodulated_log_color, pack_confidence_input,
                          pack_denoiser_input, pack_error_input, probe_exposure, radiance_exposure, white_balance_gains)
from .targets import HEATMAP_PERCENTILE, confidence_pair

ANY_SPP = "any"   # a curriculum stage: each crop draws one of its view's rendered sample counts
RGB_ORDERS = list(itertools.permutations(range(3)))   # the orders a colour permutation draws from


@dataclass(frozen=True)
class Augmentation:
    crop_min: int = 128
    crop_max: int = 256
    multiple: int = 4
    exposure_stops: float = 1.0
    aux_noise: float = 0.01
    permute_colours: bool = False


class TaskSamples(ABC):
    """The (input, target) pairs of one task over a list of views; subclasses define ``planes`` and which
    channels hold log1p radiance (``exposed_input``, ``exposed_target``: exposure scales those)."""

    aux_channels: slice = slice(0, 0)
    exposed_input: slice = slice(0, 3)
    exposed_target: slice = slice(0, 0)
    colour_inputs: tuple[slice, ...] = ()    # RGB triples a colour permutation reorders
    colour_targets: tuple[slice, ...] = ()
    # The target is the target planes themselves (``target`` as here) and the exposure acts pixel by
    # pixel, so a crop may be taken before it (exposing the crop alone: the same values for less work) and
    # the exposure applied to the whole batch; a target built from the whole frame (ErrorSamples) sets
    # this False and is exposed and made frame by frame, then cropped
    pixelwise_target: bool = True

    def __init__(self, views: list[View]):
        self.views = views
        self.items = self._items()
        self.device = torch.device("cpu")
        self._kept: dict | None = None
        self._budget, self._kept_bytes = None, 0
        self._tables: dict = {}   # index tables of the batch's gathers, by size or layout and device

    def _items(self) -> list[tuple[int, int]]:
        return [(v, f) for v, view in enumerate(self.views) for f in range(len(view.frames))]

    def keep_on(self, device: torch.device, budget: int | None = None) -> None:
        """Keep each frame's planes on ``device`` once packed (``preload``, or at their first draw), so a GPU
        does not wait for the CPU to pack frames again; without this they are packed at every draw, which
        keeps a CPU run's memory at the dataset's own size. ``budget``: keep at most this many bytes of
        them (the first drawn), packing the others at each draw; None: all."""
        self.device, self._kept, self._budget, self._kept_bytes = device, {}, budget, 0

    def preload(self, every_spp: bool, progress: bool = False, workers: int = 8) -> None:
        """Pack every frame's planes now, on ``workers`` threads, into the tensors ``keep_on`` keeps: each
        noisy render at each of its view's sample counts (``every_spp``; else at 1 spp). Packed at their
        first draws instead, they made the first epochs of a run on an H200 host-bound (5.9 steps/s over
        its first 210 steps, nearly every draw a first one), and a time budget judged by them too short."""
        from concurrent.futures import ThreadPoolExecutor

        from tqdm import tqdm

        keys = [(item, spp, copy) for item in self.items
                for spp in (self.views[item[0]].spp if every_spp else (1,)) for copy in range(self.copies(item, spp))]
        keys = [key for key in keys if key not in self._kept]
        with ThreadPoolExecutor(workers) as pool:
            packed = pool.map(lambda key: self.planes(*key), keys)
            for key, planes in tqdm(zip(keys, packed), total=len(keys), desc="pack training frames", unit="frame",
                                    disable=not progress):
                self._kept[key] = tuple(torch.from_numpy(a).to(self.device) for a in planes)

    @abstractmethod
    def planes(self, item: tuple[int, int], spp: int, copy: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """The full-frame (C, H, W) input of ``item`` from its ``copy``-th noisy render at ``spp``, and
        its target planes (what ``target`` turns into the training target), at unit exposure."""

    def target(self, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        """The training target from the (exposed) input and target planes: the planes themselves, unless a
        task derives its target from both."""
        return y

    def _tensors(self, item, spp: int, copy: int) -> tuple[torch.Tensor, torch.Tensor]:
        key = (item, spp, copy)
        if self._kept is not None and key in self._kept:
            return self._kept[key]
        tensors = tuple(torch.from_numpy(a).to(self.device) for a in self.planes(item, spp, copy))
        size = sum(t.numel() * t.element_size() for t in tensors)
        if self._kept is not None and (self._budget is None or self._kept_bytes + size <= self._budget):
            self._kept[key] = tensors
            self._kept_bytes += size
        return tensors

    def exposed(self, item, spp: int, exposure: float, copy: int = 0, window=None) -> tuple[torch.Tensor, torch.Tensor]:
        """The full-frame input and target of ``item`` (tensors on ``device``) with the radiance scaled by
        ``exposure``: log1p(v) becomes log1p(exposure · v), the same as packing the scaled render.
        ``window``: (top, left, side) of a square crop, taken before the exposure where the target is
        ``pixelwise_target`` (else after it)."""
        x, y = self._tensors(item, spp, copy)
        if window is not None and self.pixelwise_target:
            x, y = _cropped(x, window), _cropped(y, window)
        if exposure != 1.0:
            x, y = _expose(x, self.exposed_input, exposure), _expose(y, self.exposed_target, exposure)
        y = self.target(x, y)
        if window is not None and not self.pixelwise_target:
            x, y = _cropped(x, window), _cropped(y, window)
        return x, y

    def full(self, item, spp: int, exposure: float, copy: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """``exposed`` as numpy arrays (validation, tests)."""
        return tuple(t.cpu().numpy() for t in self.exposed(item, spp, exposure, copy))

    def copies(self, item: tuple[int, int], spp: int) -> int:
        """How many independent noisy renders of ``item`` at ``spp`` ``full`` can draw from."""
        return len(self.views[item[0]].frames[item[1]].renders_at(spp))

    def crop_limit(self, item, aug: Augmentation) -> int:
        """The largest crop ``item``'s frame allows under ``aug``; a batch's crop fits the least of its items'."""
        side = min(self.views[item[0]].frames[0].gold["color"].shape[:2])
        return min(aug.crop_max, side) // aug.multiple * aug.multiple

    def batch(self, items, rng: np.random.Generator, aug: Augmentation, spp: int = 1):
        """A (B, C, S, S) input batch and its targets on ``device``, augmented as the module docstring
        says: ``rng`` draws every choice, item by item; the crops are views, and the exposure, turns,
        flips, colour orders and noise are a few tensor ops on the whole batch (one gather per kind),
        however many items it holds, rather than several small ones per item: on a GPU each is a kernel
        launch, and launches, not the network's work, bound a step (BENCHMARKS.md §26).
        ``spp`` ANY_SPP: each item's sample count is drawn from its view's."""
        inputs, targets, exposures, transforms, orders = [], [], [], [], []
        # one crop size for the batch, so it fits the smallest frame in it (datasets of several sizes mix;
        # the trainer batches frames of one crop limit together: grouped_by_crop)
        largest = min(self.crop_limit(item, aug) for item in items)
        smallest = min(aug.crop_min, largest) // aug.multiple
        crop = int(rng.integers(smallest, largest // aug.multiple + 1)) * aug.multiple
        for item in items:
            exposure = float(2.0 ** rng.uniform(-aug.exposure_stops, aug.exposure_stops))
            drawn = int(rng.choice(self.views[item[0]].spp)) if spp == ANY_SPP else spp
            copy = int(rng.integers(self.copies(item, drawn)))
            height, width = self.views[item[0]].frames[item[1]].gold["color"].shape[:2]
            window = (int(rng.integers(0, height - crop + 1)), int(rng.integers(0, width - crop + 1)), crop)
            # a target made pixel by pixel is exposed with the whole batch below; one made from the
            # whole frame (ErrorSamples) needs the frame exposed first
            x, y = self.exposed(item, drawn, 1.0 if self.pixelwise_target else exposure, copy, window)
            inputs.append(x)
            targets.append(y)
            exposures.append(exposure)
            transforms.append(2 * int(rng.integers(4)) + int(rng.integers(2)))   # turns, flip
            if aug.permute_colours and self.colour_inputs:
                orders.append(RGB_ORDERS.index(tuple(rng.permutation(3))))
        x, y = torch.stack(inputs), torch.stack(targets)   # copies: the kept planes stay untouched
        if self.pixelwise_target:
            scale = _on_device(exposures, x.device).view(-1, 1, 1, 1)
            x, y = _expose(x, self.exposed_input, scale), _expose(y, self.exposed_target, scale)
        x, y = (_dihedral(a, self._dihedral_maps(crop, a.device), transforms) for a in (x, y))
        if orders:
            x = _gather_channels(x, self._colour_tables(x.shape[1], self.colour_inputs, x.device), orders)
            y = _gather_channels(y, self._colour_tables(y.shape[1], self.colour_targets, y.device), orders)
        if aug.aux_noise > 0 and self.aux_channels.stop > self.aux_channels.start:
            generator = torch.Generator(x.device).manual_seed(int(rng.integers(2 ** 63)))
            aux = x[:, self.aux_channels]
            aux += aug.aux_noise * torch.randn(aux.shape, generator=generator, device=x.device)
        return x, y

    def _dihedral_maps(self, side: int, device: torch.device) -> torch.Tensor:
        """(8, side²) source index of each pixel of a side × side crop under transform 2·turns + flip
        (torch.rot90 by ``turns`` quarter turns in the (H, W) plane, then W flipped), made once per size."""
        key = (side, device)
        if key not in self._tables:
            grid = torch.arange(side * side).view(1, side, side)
            turned = [torch.rot90(grid, turns, dims=(1, 2)) for turns in range(4)]
            maps = [m.flip(2) if flip else m for m in turned for flip in (0, 1)]
            self._tables[key] = torch.stack(maps).view(8, -1).to(device)
        return self._tables[key]

    def _colour_tables(self, channels: int, triples: tuple[slice, ...], device: torch.device) -> torch.Tensor:
        """(len(RGB_ORDERS), channels): the channel order of each colour permutation (every RGB triple
        of ``triples`` reordered, the other channels kept), made once per layout; a crop's order is a
        row of it (copying each order to a GPU would make the host wait for the device every crop)."""
        key = (channels, tuple((t.start, t.stop) for t in triples), device)
        if key not in self._tables:
            rows = np.tile(np.arange(channels), (len(RGB_ORDERS), 1))
            for row, order in zip(rows, RGB_ORDERS):
                for triple in triples:
                    row[triple] = np.arange(channels)[triple][list(order)]
            self._tables[key] = torch.from_numpy(rows).to(device)
        return self._tables[key]


def grouped_by_crop(order: np.ndarray, limits: np.ndarray, group: int) -> np.ndarray:
    """``order`` rearranged so that each run of ``group`` items (a batch; under data parallelism, one
    batch per process) shares one crop limit (``limits[i]``: item i's, TaskSamples.crop_limit), as far as
    the counts allow. A batch's crop fits its smallest frame, so a dataset of 96² frames mixed with 256²
    ones would otherwise train nearly every batch at 96². Items are dealt, in ``order``'s sequence, into a
    run per limit, each run appended when full; the runs left part-full close the order. With one
    limit, ``order`` is returned as it is."""
    if len(np.unique(limits)) <= 1:
        return order
    runs, filling = [], {}
    for index in order:
        run = filling.setdefault(int(limits[index]), [])
        run.append(int(index))
        if len(run) == group:
            runs.extend(run)
            run.clear()
    tail = [index for run in filling.values() for index in run]
    return np.array(runs + tail, dtype=order.dtype)


def _cropped(planes: torch.Tensor, window: tuple[int, int, int]) -> torch.Tensor:
    """``planes`` (C, H, W) inside the square ``window`` (top, left, side): a view."""
    top, left, side = window
    return planes[:, top:top + side, left:left + side]


def _on_device(values: list[float], device: torch.device) -> torch.Tensor:
    """``values`` as float32 on ``device``, copied without making the host wait for the device's queued
    work (a plain copy to a GPU would: pinned memory and a non-blocking copy do not)."""
    tensor = torch.tensor(values, dtype=torch.float32)
    return tensor.pin_memory().to(device, non_blocking=True) if device.type == "cuda" else tensor.to(device)


def _dihedral(batch: torch.Tensor, maps: torch.Tensor, transforms: list[int]) -> torch.Tensor:
    """Each crop of ``batch`` (B, C, S, S) turned and flipped by its transform (a row of ``maps``): one gather."""
    b, c, side, _ = batch.shape
    index = torch.stack([maps[t] for t in transforms])[:, None, :].expand(b, c, side * side)
    return batch.flatten(2).gather(2, index).view(b, c, side, side)


def _gather_channels(batch: torch.Tensor, tables: torch.Tensor, orders: list[int]) -> torch.Tensor:
    """Each crop of ``batch`` (B, C, S, S) with its channels in its order (a row of ``tables``): one gather."""
    b, c, h, w = batch.shape
    index = torch.stack([tables[k] for k in orders])[:, :, None, None].expand(b, c, h, w)
    return batch.gather(1, index)


def _expose(planes: torch.Tensor, channels: slice, exposure) -> torch.Tensor:
    """``planes`` (C, H, W), or a batch of them, with log1p radiance ``channels`` rescaled to ``exposure``
    times the radiance (a number, or a (B, 1, 1, 1) tensor: each crop's own); a copy."""
    if channels.stop <= channels.start:
        return planes
    exposed = planes.clone()
    exposed[..., channels, :, :] = torch.log1p(exposure * torch.expm1(planes[..., channels, :, :]))
    return exposed


class DenoiserSamples(TaskSamples):
    """Noisy render at ``spp`` + G-buffers → 6 target planes: log1p of gold demodulated by the noisy
    render's albedo factor and white-balanced by its gains (what the network outputs; with its exposure
    where ``auto_exposure``), then that factor times the gains (for the loss on remodulated colour, which
    is what unpack produces and the metrics score)."""

    aux_channels = slice(3, 10)
    exposed_target = slice(0, 3)
    colour_inputs = (slice(0, 3), slice(3, 6))    # log irradiance, albedo
    colour_targets = (slice(0, 3), slice(3, 6))   # gold log irradiance, albedo factor

    def __init__(self, views: list[View], auto_exposure: bool = True):
        super().__init__(views)
        self.auto_exposure = auto_exposure

    def planes(self, item, spp, copy=0):
        frame = self.views[item[0]].frames[item[1]]
        noisy = frame.renders_at(spp)[copy]
        balance = white_balance_gains(noisy["color"], noisy["albedo"], exposure=self.auto_exposure)
        x = pack_denoiser_input(noisy["color"], noisy["albedo"], noisy["normal"], noisy["depth"], spp, balance=balance)
        gold = frame.gold["color"]
        return x, np.concatenate([demodulated_log_color(gold, noisy["albedo"], balance),
                                  albedo_factor(noisy["albedo"], balance)])


class ErrorSamples(TaskSamples):
    """1-spp colour → the normalized |1 spp − gold| log-space heatmap (``targets.error_heatmap``, here in
    torch on the full exposed frame: its percentile depends on the exposure); both read at the probe's key
    (``probe_exposure``) where ``auto_exposure``."""

    exposed_target = slice(0, 3)
    pixelwise_target = False

    def __init__(self, views: list[View], auto_exposure: bool = True):
        super().__init__(views)
        self.auto_exposure = auto_exposure

    def planes(self, item, spp, copy=0):
        frame = self.views[item[0]].frames[item[1]]
        probe = frame.renders_at(1)[copy]["color"]
        exposure = probe_exposure(probe) if self.auto_exposure else 1.0
        return pack_error_input(probe, exposure), pack_error_input(frame.gold["color"], exposure)

    def target(self, x, y):
        error = (x - y).abs().mean(dim=0, keepdim=True)
        scale = torch.quantile(error.flatten(), HEATMAP_PERCENTILE / 100)
        return (error / scale).clamp(0.0, 1.0) if scale > 0 else torch.zeros_like(error)


class OnnxDenoiser:
    """A denoiser ONNX applied as ``wgpu-rt denoise`` applies it, run by onnxruntime (the WGSL engine's
    twin, held equal by the parity tests) on a render dict; ``digest`` names the file's contents (the
    confidence model's card records which denoiser's output it learned on)."""

    def __init__(self, path: str | Path):
        import hashlib

        import onnxruntime

        self.path = Path(path)
        self.digest = hashlib.sha256(self.path.read_bytes()).hexdigest()[:12]
        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = 1   # training shares 2 cores with everything else
        self.session = onnxruntime.InferenceSession(str(self.path), options, providers=["CPUExecutionProvider"])
        metadata = self.session.get_modelmeta().custom_metadata_map
        self.auto_exposure = metadata.get(INPUT_EXPOSURE) == "on"   # as the WGSL engine reads it

    def __call__(self, render: dict) -> np.ndarray:
        from ..frame.denoise import denoise

        def run(x):
            return self.session.run(None, {"input": x})[0]

        run.input_channels = self.session.get_inputs()[0].shape[1]   # denoise() packs that many planes
        return denoise(run, render["color"], render["albedo"], render["normal"], render["depth"],
                       auto_exposure=self.auto_exposure)


class ConfidenceSamples(TaskSamples):
    """Frame t+1 as the temporal pass's source (1 spp, denoised by ``denoiser``, an OnnxDenoiser) + gold
    frame t reprojected as the runtime's temporal pass does (zero where its depth/normal tests find no
    matching texel) → confidence that history is valid: 1 minus the disocclusion mask (needs sequences).
    The reprojection is a per-pixel reference and denoising a network run, so each pair's are computed
    once; exposure scales source and history alike (reprojection is linear in colour; the denoiser
    nearly so). Where ``auto_exposure`` both are read at the source's key (``radiance_exposure`` to
    CONFIDENCE_KEY), as the temporal pass reads them for a model whose file says so."""

    aux_channels = slice(6, 8)
    exposed_input = slice(0, 6)

    def _items(self):
        return [(v, t) for v, view in enumerate(self.views) for t in range(len(view.frames) - 1)]

    def __init__(self, views: list[View], denoiser, auto_exposure: bool = True):
        super().__init__(views)
        self.denoiser, self.auto_exposure = denoiser, auto_exposure
        self._pairs = {}

    def _pair(self, item):
        """(source, history RGB, history depth, tested, mask) of ``item``, computed once."""
        if item not in self._pairs:
            view = self.views[item[0]]
            previous, current = view.frames[item[1]], view.frames[item[1] + 1]
            self._pairs[item] = (self.denoiser(current.noisy[1]), *confidence_pair(previous, current))
        return self._pairs[item]

    def copies(self, item, spp):
        return 1   # each pair's denoised source is computed once, from the frame's first 1-spp render

    def planes(self, item, spp, copy=0):
        source, history, history_depth, _, mask = self._pair(item)
        depth = self.views[item[0]].frames[item[1] + 1].noisy[1]["depth"]
        exposure = radiance_exposure(source, CONFIDENCE_KEY) if self.auto_exposure else 1.0
        return pack_confidence_input(source, history, depth, history_depth, exposure), 1.0 - mask[None]

    def tested(self, item) -> np.ndarray:
        """(H, W) bool: the pixels of ``item`` whose history passes the temporal pass's depth/normal tests."""
        return self._pair(item)[3]


def samples_for(task: str, views: list[View], denoiser: OnnxDenoiser | None = None,
                auto_exposure: bool = True) -> TaskSamples:
    """The task's samples; the confidence model's need the ``denoiser`` that makes its current frame; the
    networks' inputs are brought to one exposure where ``auto_exposure`` (frame/pack.py)."""
    if task == "confidence":
        return ConfidenceSamples(views, denoiser, auto_exposure)
    if task == "denoiser":
        return DenoiserSamples(views, auto_exposure)
    return ErrorSamples(views, auto_exposure)


def curriculum_spp(progress: float, available: list[int], stages: tuple[int | str, ...] = (16, 4, 1)) -> int | str:
    """The sample count for training ``progress`` ∈ [0, 1): equal shares of ``stages`` (by default
    thirds of 16, 4 and 1 spp; repeat a stage to give it more); stages the dataset lacks are skipped (with
    no count every view has, each crop draws from its own view's: ANY_SPP)."""
    usable = [s for s in stages if s in available or s == ANY_SPP] or [min(available, default=ANY_SPP)]
    return usable[min(int(progress * len(usable)), len(usable) - 1)]
