"""The training loop shared by the three networks: Adam with warm-up + cosine decay, gradient-norm clipping,
checkpoints at epoch ends (resumable: after a session's first epoch, then once CHECKPOINT_SECONDS have
passed, and after the last), validation on held-out views every epoch (or every N: on a CPU it can cost
more than the epoch's training), then ONNX export with a model card.

An epoch is one pass over the training items (view frames, or frame pairs for the confidence model) in
a shuffled order, in batches. Validation uses the ``val`` split, which no training batch ever touches:
the denoiser is scored at 1 spp on full frames (PSNR, SSIM, relMSE, FLIP against gold), the error
predictor by the Spearman correlation of its heatmap with the true error, the confidence model by the
ROC AUC of its output against the true disocclusion mask (``confidence_aucs``' three ways).

Where it runs (CPU or CUDA, mixed precision, several processes under torchrun) is ``context``'s; a
checkpoint is read onto the CPU and moved to this run's device, so a run resumes on another device or
machine. Every
setting and output path is checked before any data is read or any file written.
"""

from __future__ import annotations

import copy
import hashlib
import math
import re
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..dataset.store import load_views
from ..errors import WgpuRtError
from ..frame.denoise import pad_to_multiple
from ..models import Network, network_named
from ..io import atomic_output, check_output_path
from .cards import embedded_card
from .context import TrainContext, training_context
from .samples import ANY_SPP, Augmentation, curriculum_spp, grouped_by_crop, samples_for

# Checkpoints wait this long after the last one (a crash loses at most this much training): a CUDA epoch
# of a large batch over a few hundred views is a handful of steps, and writing the model and Adam's
# state at each of its ends would take a share of the run (an estimate, BENCHMARKS.md §26)
CHECKPOINT_SECONDS = 60.0
# The progress bar shows a step's loss once in this many steps (reading it waits for the step on a GPU)
PROGRESS_LOSS_STEPS = 50
# Settings a resumed run may change: more epochs stretch the schedule; the rest is bookkeeping.
RESUMABLE_CHANGES = {"epochs", "resume", "out", "checkpoints", "validate_every", "device", "minutes"}


class TrainingError(WgpuRtError):
    """Training cannot go on: no usable data, or the loss became NaN/Inf."""


@dataclass
class TrainConfig:
    task: str
    data: str
    out: str = "models"
    epochs: int = 20
    batch: int = 4
    lr: float = 1e-3
    seed: int = 0
    extra_data: tuple[str, ...] = ()     # more datasets: their train/val splits join ours (never test)
    crop_min: int = 128
    crop_max: int = 256
    pixel_loss: str = "l1"               # or "charbonnier"
    ssim_space: str = "log"              # or "display" (the metrics' Reinhard + gamma mapping)
    lowpass: float = 0.0                 # weight of the denoiser's 8×8 block-mean L1 term (0: none)
    log_mse: float = 0.0                 # weight of the denoiser's per-crop log display-MSE term (0: none)
    edge: float = 0.0                    # weight of the denoiser's display L1 near aux edges (0: none)
    permute_colours: bool = False        # a random RGB order per crop (samples.Augmentation)
    auto_exposure: bool = True           # the network's input brought to one key (frame/pack.py), as its
                                         # ONNX file then records (frame/denoise_chain.py's INPUT_EXPOSURE)
    widths: tuple[int, ...] = (32, 64, 128)
    residual: bool = False               # denoiser predicts a correction to its noisy input
    bottom_merge: str = "concat"         # or "add": the denoiser's deepest level added to the skip above
    curriculum: tuple[int | str, ...] = (16, 4, 1)   # denoiser spp per equal share of the epochs (ANY_SPP: per crop)
    grad_clip: float = 1.0
    resume: bool = False
    max_views: int | None = None
    checkpoints: str | None = None       # default OUT/checkpoints
    init_from: str | None = None         # fine-tune: start from this checkpoint's weights (fresh optimizer)
    validate_every: int = 1              # epochs between validations (the last epoch is always validated)
    device: str = "auto"                 # cuda, cpu, or auto: CUDA when torch sees it
    minutes: float | None = None         # a time budget: fewer epochs when the first ones show they won't fit

    @property
    def network(self) -> Network:
        """The network trained (``task`` in either spelling: error_predictor or error-predictor)."""
        return network_named(self.task)

    @property
    def model_name(self) -> str:
        return self.network.name

    def check(self) -> None:
        """A clear error naming the flag for any setting training cannot run with, before any work."""
        try:
            self.network
        except KeyError as err:
            raise TrainingError(err.args[0]) from None
        counts = {"--epochs": [self.epochs], "--batch": [self.batch], "--widths": self.widths,
                  "--curriculum": [1 if stage == ANY_SPP else stage for stage in self.curriculum],
                  "--validate-every": [self.validate_every],
                  "--crop": [self.crop_min, self.crop_max],
                  "--max-views": [] if self.max_views is None else [self.max_views]}
        for flag, values in counts.items():
            if any(value < 1 for value in values):
                raise TrainingError(f"{flag} must be at least 1, got {' '.join(map(str, values))}")
        if self.crop_min > self.crop_max:
            raise TrainingError(f"--crop MIN MAX: min {self.crop_min} is larger than max {self.crop_max}")
        if not (math.isfinite(self.lr) and self.lr > 0):
            raise TrainingError(f"--lr must be a positive number, got {self.lr}")
        if self.minutes is not None and not (math.isfinite(self.minutes) and self.minutes > 0):
            raise TrainingError(f"--minutes must be a positive number, got {self.minutes}")
        for flag, weight in (("--lowpass", self.lowpass), ("--log-mse", self.log_mse), ("--edge", self.edge)):
            if not (math.isfinite(weight) and weight >= 0):
                raise TrainingError(f"{flag} must be a loss weight of 0 or more, got {weight}")
        if self.init_from is not None and not Path(self.init_from).is_file():
            raise TrainingError(f"--init-from {self.init_from}: no such checkpoint or ONNX file")
        checkpoint, *exported = self.outputs()
        for path in exported:
            check_output_path(path, "--out")
        check_output_path(checkpoint, "--checkpoints" if self.checkpoints else "--out")

    @property
    def checkpoint_path(self) -> Path:
        return Path(self.checkpoints or Path(self.out) / "checkpoints") / f"{self.model_name}.pt"

    def outputs(self) -> tuple[Path, Path, Path]:
        """The files a run writes: the checkpoint, the ONNX and its model card."""
        out = Path(self.out)
        return self.checkpoint_path, out / f"{self.model_name}.onnx", out / f"{self.model_name}.md"


def build_model(config: TrainConfig):
    from .networks import ConfidencePredictor, ErrorPredictor, UNet

    if config.task == "denoiser":
        return UNet(widths=tuple(config.widths), residual=config.residual, bottom_merge=config.bottom_merge)
    if config.model_name == "error_predictor":
        return ErrorPredictor()
    return ConfidencePredictor()


def rank_correlation(a, b) -> float:
    from scipy.stats import spearmanr

    value = spearmanr(np.ravel(a), np.ravel(b)).statistic
    return float(value) if np.isfinite(value) else 0.0


def roc_auc(scores, labels) -> float:
    """Area under the ROC curve by the Mann–Whitney rank sum (0.5 when one class is absent)."""
    from scipy.stats import rankdata

    scores, labels = np.ravel(scores), np.ravel(labels) > 0.5
    positives, negatives = int(labels.sum()), int((~labels).sum())
    if positives == 0 or negatives == 0:
        return 0.5
    ranks = rankdata(scores)
    return float((ranks[labels].sum() - positives * (positives + 1) / 2) / (positives * negatives))


def confidence_aucs(confidence, mask, tested) -> dict[str, float]:
    """ROC AUC of 1 − ``confidence`` (the model says "history valid") against the disocclusion ``mask``
    in three ways: over all pixels (``roc_auc``); over the ``tested`` pixels, whose history passes the
    temporal pass's depth/normal tests, the only ones where the model decides anything
    (``roc_auc_tested``); and for the temporal stage as a whole, failed tests counting as certain
    disocclusion (``roc_auc_stage``)."""
    invalid = 1.0 - np.asarray(confidence)
    return {"roc_auc": roc_auc(invalid, mask), "roc_auc_tested": roc_auc(invalid[tested], mask[tested]),
            "roc_auc_stage": roc_auc(np.where(tested, invalid, 1.0), mask)}


class Trainer:
    def __init__(self, config: TrainConfig, progress: bool = True, context: TrainContext | None = None):
        """``context``: where to train (default: ``training_context(config.device)``). ``progress``: a line per
        epoch, and where stderr is a terminal progress bars (piped into a log they would be noise)."""
        import sys

        import torch

        config.check()
        self.config = config
        self.context = context or training_context(config.device)
        self.progress = progress and self.context.main
        self.bars = self.progress and sys.stderr.isatty()
        torch.manual_seed(config.seed)
        self.model = build_model(config).to(self.context.device)
        self.multiple = getattr(self.model, "multiple", 1)
        self.smallest_crop = self._smallest_crop()
        if config.crop_min < self.smallest_crop:
            raise TrainingError(f"--crop MIN must be at least {self.smallest_crop} for the {config.task} "
                                f"({self._crop_reason()}), got {config.crop_min}")
        folders = (config.data, *config.extra_data)
        for folder in folders:
            self._dataset_line(folder)   # the card reads each manifest at the end: check it first
        denoiser = self._source_denoiser() if config.task == "confidence" else None
        self.train_set, self.val_set = (
            samples_for(config.model_name, [v for folder in folders for v in load_views(folder, split, config.max_views)],
                        denoiser, config.auto_exposure)
            for split in ("train", "val"))
        for name, subset in (("train", self.train_set), ("val", self.val_set)):
            if not subset.items:
                need = " (the confidence model needs temporal sequences)" if config.task == "confidence" else ""
                if name == "val" and not need:
                    need = (" (`wgpu-rt dataset` holds back a tenth of a dataset's worlds or views for validation, "
                            "from 3 of them up: render more, or add a dataset that has some with --extra-data)")
                raise TrainingError(f"{', '.join(folders)}: no {name} samples for {config.task}{need}")
        frame = min(min(view.frames[0].gold["color"].shape[:2]) for view in self.train_set.views)
        if frame // self.multiple * self.multiple < self.smallest_crop:
            raise TrainingError(f"{', '.join(folders)}: {frame}-px frames are too small to train the {config.task} "
                                f"on ({self._crop_reason()}: at least {self.smallest_crop} px)")
        if self.context.keep_data or self.context.host_budget:
            self.train_set.keep_on(self.context.device, self.context.host_budget)
        self.network = self.context.wrap(self.model)
        self.steps_per_epoch = math.ceil(len(self.context.shard(np.arange(len(self.train_set.items))))
                                         / config.batch)
        self.total_steps = self.steps_per_epoch * config.epochs
        # on CUDA one fused kernel updates every parameter (a step's launches bound it, BENCHMARKS.md §26)
        self.optimizer = torch.optim.Adam(self.model.parameters(), lr=config.lr,
                                          fused=self.context.device.type == "cuda")
        self.schedule = torch.optim.lr_scheduler.LambdaLR(self.optimizer, self.learning_rate_factor)
        self.augmentation = Augmentation(config.crop_min, config.crop_max, self.multiple,
                                         permute_colours=config.permute_colours)
        self.crop_limits = np.array([self.train_set.crop_limit(item, self.augmentation)
                                     for item in self.train_set.items])
        # Rank 0 draws each epoch's order (shared with the others) and its own augmentations, as a single
        # process does; the other ranks draw their augmentations from streams of their own.
        rank = self.context.rank
        self.rng = np.random.default_rng(config.seed if rank == 0 else (config.seed, rank))
        self.epoch, self.step, self.seconds, self.history = 0, 0, 0.0, []
        self.epochs_asked: int | None = None   # set when --minutes cut the epochs
        self.timed = {"steps": 0, "seconds": 0.0}   # this session's training steps and their time
        self.checkpoint_path = config.checkpoint_path
        self._saved_at: float | None = None   # this session's last checkpoint (perf_counter)
        self.base: dict | None = None     # the run a fine-tune starts from: its path, epochs, time, metrics
        if config.resume and self.checkpoint_path.exists():
            self._load_checkpoint()
        elif config.init_from:
            self._load_initial_weights(Path(config.init_from))

    def _smallest_crop(self) -> int:
        """The smallest crop that trains: a multiple of the network's size multiple, and for the denoiser
        at least its SSIM loss's window."""
        from .losses import SSIM_WINDOW

        least = SSIM_WINDOW if self.config.task == "denoiser" else 1
        return -(-least // self.multiple) * self.multiple

    def _crop_reason(self) -> str:
        window = ", and the SSIM loss's 11-px window" if self.config.task == "denoiser" else ""
        return f"crops are multiples of {self.multiple}{window}"

    def _source_denoiser(self):
        """The confidence model judges history against the temporal pass's source, the *denoised* frame:
        OUT/denoiser.onnx makes it (the recipe trains the denoiser first)."""
        from .samples import OnnxDenoiser

        path = Path(self.config.out) / "denoiser.onnx"
        if not path.is_file():
            raise TrainingError(f"{path}: no denoiser; the confidence model learns on the denoised frame the "
                                "runtime feeds it, so train the denoiser into the same --out first")
        return OnnxDenoiser(path)

    def learning_rate_factor(self, step: int) -> float:
        """Linear warm-up over the first 5 % of steps, then cosine decay to 0 at ``total_steps`` (read
        live, so a resumed run with more epochs stretches the decay)."""
        warmup = max(1, self.total_steps // 20)
        progress = min(step / max(self.total_steps, 1), 1.0)
        return min(1.0, (step + 1) / warmup) * 0.5 * (1.0 + math.cos(math.pi * progress))

    # -- checkpoints -------------------------------------------------------------------------------
    def _save_checkpoint(self) -> None:
        """Rank 0 writes the checkpoint (with every rank's random state, so a resumed data-parallel run
        draws what the uninterrupted one would have)."""
        import torch

        rngs = self.context.gather(self.rng.bit_generator.state)
        if not self.context.main:
            return
        state = {"model": self.model.state_dict(), "optimizer": self.optimizer.state_dict(),
                 "schedule": self.schedule.state_dict(), "scaler": self.context.scaler.state_dict(),
                 "epoch": self.epoch, "step": self.step, "seconds": self.seconds,
                 "history": self.history, "rng": rngs[0], "rank_rngs": rngs,
                 "torch_rng": torch.get_rng_state(), "config": asdict(self.config), "base": self.base}
        with atomic_output(self.checkpoint_path) as tmp:
            torch.save(state, tmp)

    def _load_checkpoint(self) -> None:
        import torch

        state = self._load_weights(self.checkpoint_path, "resume from")
        changed = self._changed_settings(state.get("config", {}))
        if changed:
            raise TrainingError(f"{self.checkpoint_path}: trained with other settings ({', '.join(changed)}); "
                                "delete it or pass another --checkpoints folder to start afresh")
        self.optimizer.load_state_dict(state["optimizer"])   # moves its state onto the parameters' device
        self.schedule.load_state_dict(state["schedule"])
        if state.get("scaler"):
            self.context.scaler.load_state_dict(state["scaler"])
        self.epoch, self.step, self.seconds = state["epoch"], state["step"], state["seconds"]
        self.history, self.base = state["history"], state.get("base")
        rngs = state.get("rank_rngs", [state["rng"]])
        if self.context.rank < len(rngs):   # a rank the saved run lacked keeps its fresh stream
            self.rng.bit_generator.state = rngs[self.context.rank]
        torch.set_rng_state(state["torch_rng"])

    def _load_weights(self, path: Path, purpose: str) -> dict:
        """The checkpoint at ``path``, its weights loaded into the model; a clear error if it cannot be."""
        import torch

        try:
            state = torch.load(path, map_location="cpu", weights_only=False)   # saved on any device
            self.model.load_state_dict(state["model"])
        except Exception as err:  # torch raises many types for missing, corrupt or mismatched files
            raise TrainingError(f"{path}: cannot {purpose} this checkpoint ({err})") from None
        return state

    def _load_onnx_weights(self, path: Path) -> dict:
        """The weights of an exported model (e.g. the shipped ``models/denoiser.onnx``: torch's export keeps
        the parameter names) loaded into the model; a checkpoint-like record without history."""
        import onnx
        import torch
        from onnx import numpy_helper

        try:
            weights = {i.name: numpy_helper.to_array(i) for i in onnx.load(str(path)).graph.initializer}
        except Exception as err:  # onnx raises several types for missing or corrupt files
            raise TrainingError(f"{path}: cannot read this ONNX model ({err})") from None
        expected = self.model.state_dict()
        weights = _deepened(_with_new_input_channels(weights, expected), expected)
        weights = _widened(_narrowed(weights, expected), expected)
        wrong = [name for name, tensor in expected.items()
                 if name not in weights or tuple(weights[name].shape) != tuple(tensor.shape)]
        if wrong:
            raise TrainingError(f"{path}: not a {self.config.network.cli_name} with these --widths "
                                f"(parameter {wrong[0]!r} missing or of another shape)")
        self.model.load_state_dict({name: torch.from_numpy(weights[name].copy()) for name in expected})
        card = path.with_suffix(".md")
        return {"onnx": hashlib.sha256(path.read_bytes()).hexdigest()[:12],
                "card": card.read_text(encoding="utf-8") if card.is_file() else None}

    def _load_initial_weights(self, path: Path) -> None:
        """Fine-tuning: the weights of another run's checkpoint, or of an exported ONNX model (same task and
        architecture); the optimizer, schedule and history start afresh, and the model card credits the base
        run's epochs and time."""
        if path.resolve() == self.checkpoint_path.resolve():
            raise TrainingError(f"{path}: --init-from is this run's own checkpoint; pass another --checkpoints "
                                "folder for the fine-tune")
        state = self._load_onnx_weights(path) if path.suffix.lower() == ".onnx" else self._load_weights(path, "start from")
        validated = [h for h in state.get("history", []) if any(k.startswith("val_") for k in h)]
        self.base = {"path": str(path), "epochs": state.get("epoch", 0), "seconds": state.get("seconds", 0.0),
                     "base": state.get("base"), "onnx": state.get("onnx"), "card": state.get("card"),
                     "metrics": {k: v for k, v in (validated[-1] if validated else {}).items() if k.startswith("val_")}}

    def _changed_settings(self, saved: dict) -> list[str]:
        """Names of the settings (beyond RESUMABLE_CHANGES) where ``saved`` differs from this run's; a
        setting the checkpoint predates is not compared."""
        same = lambda a, b: (tuple(a) == tuple(b)) if isinstance(a, (list, tuple)) else a == b  # noqa: E731
        return sorted(key for key, value in asdict(self.config).items()
                      if key in saved and key not in RESUMABLE_CHANGES and not same(saved[key], value))

    # -- training ----------------------------------------------------------------------------------
    def loss(self, prediction, target, x):
        """The task's loss of ``prediction`` against ``target``; ``x``, the network's input, shows the
        denoiser's edge term where the aux planes' edges lie."""
        import torch.nn.functional as F

        from .losses import denoiser_loss

        if self.config.task == "denoiser":
            cfg = self.config
            aux = x[:, self.train_set.aux_channels].float() if cfg.edge else None
            return denoiser_loss(prediction, target, cfg.pixel_loss, cfg.ssim_space, cfg.lowpass, cfg.log_mse,
                                 cfg.edge, aux)
        if self.config.task == "confidence":
            # Disocclusions (target 0: history invalid) are rare: weight them by the batch's class ratio.
            invalid = (1 - target).mean().clamp(0.01, 0.99)
            weight = (1 - target) * (1 - invalid) / invalid + target
            return F.binary_cross_entropy(prediction.clamp(1e-6, 1 - 1e-6), target, weight=weight)
        return F.binary_cross_entropy(prediction.clamp(1e-6, 1 - 1e-6), target)

    def train_step(self, items, spp: int):
        """One optimizer step on ``items``; returns this process's loss as a tensor on the device: reading
        it would make the host wait for the step, so run() reads an epoch's losses at its end."""
        import torch

        x, y = self.train_set.batch(items, self.rng, self.augmentation, spp)
        x = x.contiguous(memory_format=self.context.memory_format)
        self.network.train()
        with self.context.autocast():
            prediction = self.network(x)
        loss = self.loss(prediction.float(), y, x)   # the loss in float32 whatever the network ran in
        scaler = self.context.scaler   # float16 only: scales the loss so small gradients survive
        self.optimizer.zero_grad(set_to_none=True)
        scaler.scale(loss).backward()
        scaler.unscale_(self.optimizer)
        torch.nn.utils.clip_grad_norm_(self.model.parameters(), self.config.grad_clip)
        scaler.step(self.optimizer)
        scaler.update()
        self.schedule.step()
        self.step += 1
        return loss.detach()

    def _epoch_losses(self, losses: list, first_step: int) -> np.ndarray:
        """The epoch's per-step losses, each averaged over the data-parallel ranks, read from the device
        once (all ranks see the same values, so they stop together); a step whose loss was not finite
        stops training here, before the epoch's checkpoint, so the last checkpoint holds finite weights."""
        import torch

        values = self.context.mean_each(torch.stack(losses)) if losses else np.zeros(0)
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):
            raise TrainingError(f"{self.config.task}: loss became {values[bad[0]]} at step {first_step + bad[0]} "
                                f"(epoch {self.epoch}); lower --lr, or check {self.config.data} for bad images")
        return values

    def run(self) -> dict:
        """Train the remaining epochs (all, or those after a resumed checkpoint); returns the last
        validation metrics."""
        from tqdm import tqdm

        # a fixed stage must be rendered for every view; 'any' draws from each view's own counts
        available = sorted(set.intersection(*(set(view.spp) for view in self.train_set.views)))
        session_started = time.perf_counter()
        if self.context.keep_data:
            self.train_set.preload(every_spp=self.config.task == "denoiser", progress=self.bars)
        epoch_ends = [time.perf_counter()]   # the training's start, then each epoch's end (checkpoint included)
        with tqdm(total=self.total_steps, initial=self.step, desc=f"train {self.config.task}", unit="step",
                  disable=not self.bars) as bar:
            while self.epoch < self.config.epochs:
                started = time.perf_counter()
                order = self.context.broadcast(self.rng.permutation(len(self.train_set.items))
                                               if self.context.main else None)
                order = self.context.shard(grouped_by_crop(order, self.crop_limits,
                                                           self.config.batch * self.context.world_size))
                spp = (curriculum_spp(self.epoch / self.config.epochs, available, tuple(self.config.curriculum))
                       if self.config.task == "denoiser" else 1)
                losses, first_step = [], self.step
                for first in range(0, len(order), self.config.batch):
                    items = [self.train_set.items[i] for i in order[first:first + self.config.batch]]
                    losses.append(self.train_step(items, spp))
                    bar.update(1)
                    if self.bars and len(losses) % PROGRESS_LOSS_STEPS == 0:   # one wait per that many steps
                        bar.set_postfix(loss=f"{float(losses[-1]):.4f}", spp=spp)
                losses = self._epoch_losses(losses, first_step)
                bar.set_postfix(loss=f"{np.mean(losses):.4f}", spp=spp)
                self._synchronize()
                steps_seconds = time.perf_counter() - started
                self.timed["steps"] += len(losses)
                self.timed["seconds"] += steps_seconds
                self.epoch += 1
                epoch_ends.append(time.perf_counter())
                self._fit_epochs_to_minutes(epoch_ends[-1] - session_started, np.diff(epoch_ends))
                bar.total = self.total_steps
                due = self.epoch % self.config.validate_every == 0 or self.epoch == self.config.epochs
                metrics = self.validate() if due and self.context.main else {}
                self.seconds += time.perf_counter() - started
                self.history.append({"epoch": self.epoch, "step": self.step, "spp": spp,
                                     "train_loss": float(np.mean(losses)), "steps_seconds": steps_seconds,
                                     **metrics, **self.throughput()})
                if self.progress:   # (tqdm.write keeps a bar below the line; without one it prints)
                    bar.write(f"epoch {self.epoch}: " + ", ".join(
                        f"{k} {v:.4g}" for k, v in self.history[-1].items() if isinstance(v, float)))
                if self._checkpoint_due():
                    self._save_checkpoint()
        return self.history[-1] if self.history else {}

    def _checkpoint_due(self) -> bool:
        """Whether this epoch's end writes a checkpoint: the session's first, the run's last, or one
        CHECKPOINT_SECONDS after the last written. Rank 0's clock decides for every process (the
        checkpoint gathers every rank's random state)."""
        now = time.perf_counter()
        due = self.context.broadcast((self._saved_at is None or self.epoch >= self.config.epochs
                                      or now - self._saved_at >= CHECKPOINT_SECONDS) if self.context.main else None)
        if due:
            self._saved_at = now
        return due

    def _fit_epochs_to_minutes(self, seconds: float, epoch_seconds) -> None:
        """With ``minutes``, set the epochs to those that fit the budget (``seconds`` of it spent, data
        preloading included) at this session's pace, so the learning-rate schedule still decays to its end
        inside it: never below the epochs already done nor above those asked. The pace is that of the
        epochs after the first (``epoch_seconds``: this session's, validations and checkpoints included),
        which carries the warm-up; each epoch's end judges again. Rank 0's clock decides for every process."""
        asked = self.epochs_asked or self.config.epochs
        if self.config.minutes is None or self.epoch >= self.config.epochs:
            return
        pace = float(np.mean(epoch_seconds[1:] if len(epoch_seconds) > 1 else epoch_seconds))
        fits = self.context.broadcast(self.epoch + int(max(self.config.minutes * 60 - seconds, 0.0) // pace))
        epochs = max(self.epoch, min(fits, asked))
        self.epochs_asked = asked if epochs < asked else None
        self.config.epochs = epochs
        self.total_steps = self.steps_per_epoch * epochs

    def _synchronize(self) -> None:
        """Wait for the device's queued work, so the time measured is the work's."""
        import torch

        if self.context.device.type == "cuda":
            torch.cuda.synchronize(self.context.device)

    def throughput(self) -> dict[str, float]:
        """This session's training speed on this hardware (validation and checkpoints excluded): optimizer
        steps per second and training views per hour (crops of view frames, all processes together)."""
        if not self.timed["seconds"]:
            return {}
        steps_per_s = self.timed["steps"] / self.timed["seconds"]
        return {"steps_per_s": steps_per_s,
                "views_per_hour": steps_per_s * 3600 * self.config.batch * self.context.world_size}

    # -- validation --------------------------------------------------------------------------------
    def predict(self, x: np.ndarray) -> np.ndarray:
        """The model on one full (C, H, W) input, padded to its size multiple and cropped back."""
        import torch

        self.model.eval()
        with torch.no_grad():
            padded = pad_to_multiple(x[None], self.multiple)
            out = self.model(torch.from_numpy(padded).to(self.context.device)).cpu().numpy()[0]
        return out[:, :x.shape[1], :x.shape[2]]

    def validate(self) -> dict[str, float]:
        from .. import metrics
        from ..frame.pack import white_balance_gains
        from ..frame.unpack import unpack_denoiser_output

        scores: dict[str, list[float]] = {}
        for item in self.val_set.items:
            x, y = self.val_set.full(item, 1, 1.0)
            out = self.predict(x)
            if self.config.task == "denoiser":
                frame = self.val_set.views[item[0]].frames[item[1]]
                noisy = frame.noisy[1]
                gains = white_balance_gains(noisy["color"], noisy["albedo"], exposure=self.config.auto_exposure)
                denoised = unpack_denoiser_output(out, noisy["albedo"], gains)
                values = metrics.all_metrics(frame.gold["color"], denoised)
            elif self.config.model_name == "error_predictor":
                values = {"spearman": rank_correlation(out, y)}
            else:
                values = confidence_aucs(out[0], 1.0 - y[0], self.val_set.tested(item))
            for key, value in values.items():
                scores.setdefault(key, []).append(value)
        return {f"val_{k}": float(np.mean(v)) for k, v in scores.items()}

    # -- export ------------------------------------------------------------------------------------
    def export(self) -> tuple[Path, Path]:
        """``OUT/<name>.onnx`` and its model card ``OUT/<name>.md``."""
        from ..frame.denoise_chain import INPUT_EXPOSURE
        from .networks import export_onnx

        _, onnx_path, card = self.config.outputs()
        metadata = {INPUT_EXPOSURE: "on" if self.config.auto_exposure else "off"}
        export_onnx(copy.deepcopy(self.model).cpu(), onnx_path, metadata=metadata)   # traced on the CPU
        with atomic_output(card) as tmp:
            tmp.write_text(self.model_card())
        return onnx_path, card

    @staticmethod
    def _dataset_line(folder: str) -> str:
        from ..dataset.store import read_manifest
        from ..dataset.truth import WORLD_VIEW_PREFIX

        manifest = read_manifest(folder)
        dataset = manifest.get("config", {})
        render_minutes = sum(v.get("seconds", 0.0) for v in manifest["views"]) / 60
        copies = int(dataset.get("noisy_copies", 1))
        worlds = int(dataset.get("worlds") or 0)
        scenes = ", ".join(dataset.get("scenes", []))
        rendered = sum(view.get("scene", "").startswith(WORLD_VIEW_PREFIX) for view in manifest["views"])
        share = f"{rendered} of {worlds}" if rendered < worlds else f"{worlds}"   # fewer: a stopped render
        content = (f"{share} generated worlds of the {dataset.get('family', 'training')} family"
                   + (f" and scenes {scenes}" if scenes else "")) if worlds else f"scenes {scenes}"
        return (f"- dataset `{folder}` (seed {dataset.get('seed')}), rendered by `wgpu-rt dataset` on this machine's "
                f"adapter: {content}; {dataset.get('size')}² px; noisy at "
                f"{dataset.get('spp')} spp"
                + (f" ({copies} independent renders of each frame at {min(dataset['spp'])} spp)" if copies > 1 else "")
                + f"; gold at {dataset.get('gold')} spp"
                + (" by Mitsuba 3" if dataset.get("gold_renderer") == "mitsuba" else "")
                + f"; max depth {dataset.get('max_depth')}; "
                + _older_guide_albedo(int(dataset.get("guide_albedo", 1)))
                + f"{len(manifest['views'])} views rendered in {render_minutes:.1f} min")

    def _base_runs(self) -> list[dict]:
        """The runs this one was fine-tuned from, nearest first."""
        runs, base = [], self.base
        while base:
            runs.append(base)
            base = base.get("base")
        return runs

    def model_card(self) -> str:
        from ..dataset.store import read_manifest
        from ..frame.pack import ALBEDO_EPSILON, CONFIDENCE_KEY, EXPOSURE_KEY, PROBE_KEY
        from .losses import EDGE_REACH, LOG_MSE_FLOOR

        cfg = self.config
        last = self.history[-1] if self.history else {}
        train_views = {v for v, _ in self.train_set.items}
        val_views = {v for v, _ in self.val_set.items}
        gold = min(int(read_manifest(folder).get("config", {}).get("gold", 0)) for folder in (cfg.data, *cfg.extra_data))
        copied = any(self.train_set.copies(item, 1) > 1 for item in self.train_set.items)
        parameters = sum(p.numel() for p in self.model.parameters())
        lines = [
            f"# {cfg.model_name}.onnx — {cfg.task}",
            "",
            f"Trained by `wgpu-rt train {cfg.network.cli_name}` (wgpu_rt/train). {parameters:,} parameters"
            + (f", UNet widths {tuple(cfg.widths)}" + (", residual (output = input log1p RGB + correction)"
                                                        if cfg.residual else "")
               + (", deepest level added to the skip above it (no merge convs there)"
                  if cfg.bottom_merge == "add" else "")
               if cfg.task == "denoiser" else "") + ".",
            "",
            "## Data",
            *(self._dataset_line(folder) for folder in (cfg.data, *cfg.extra_data)),
            f"- training views: {len(train_views)} ({len(self.train_set.items)} samples); validation views "
            f"(never trained on): {len(val_views)} ({len(self.val_set.items)} samples)",
            "",
            "## Recipe",
            f"- epochs {cfg.epochs}"
            + (f" (of {self.epochs_asked} asked: cut to fit --minutes {cfg.minutes:g})" if self.epochs_asked else "")
            + f", steps {self.step}, batch {cfg.batch}, Adam, LR {cfg.lr} with warm-up + cosine decay, "
            f"grad-norm clip {cfg.grad_clip}, seed {cfg.seed}",
            f"- crops {cfg.crop_min}–{cfg.crop_max} px (clamped to the frame"
            + ("; each batch from frames of one crop limit: " + ", ".join(
                f"{np.count_nonzero(self.crop_limits == limit)} frames up to {limit} px"
                for limit in np.unique(self.crop_limits)) if len(np.unique(self.crop_limits)) > 1 else "")
            + "), flips + 90° rotations, "
            "exposure jitter ±1 stop, aux-channel noise σ 0.01"
            + (", a random RGB order per crop" if cfg.permute_colours else "")
            + ("; each draw takes a random one of a frame's independent 1-spp renders" if copied else ""),
        ]
        if cfg.task == "denoiser":
            lines.append("- input and output colour demodulated by albedo and white-balanced: log1p(colour / "
                         f"((albedo + {ALBEDO_EPSILON}) · gain)), the gains the square roots of the frame's mean "
                         "irradiance per channel over their mean"
                         + (", times the frame's exposure scale (its irradiance's key, the log-average of 8×8 "
                            f"tile means, brought to {EXPOSURE_KEY}; the ONNX file records it)"
                            if cfg.auto_exposure else "; no exposure step (the ONNX file records it)")
                         + "; unpack multiplies back")
            drawn = "; 'any': each crop draws one of its view's sample counts" if ANY_SPP in cfg.curriculum else ""
            lines.append(f"- loss 0.8·(1 − SSIM on {cfg.ssim_space} colour) + 0.2·{cfg.pixel_loss} on log1p "
                         "irradiance" + (f" + {cfg.lowpass:g}·L1 of its 8×8 block means" if cfg.lowpass else "")
                         + (f" + {cfg.log_mse:g}·mean over crops of log10(1 + display MSE / {LOG_MSE_FLOOR:g})"
                            if cfg.log_mse else "")
                         + (f" + {cfg.edge:g}·display L1 within {EDGE_REACH} px of the aux planes' edges"
                            if cfg.edge else "")
                         + f"; curriculum {' → '.join(map(str, cfg.curriculum))} spp (equal shares of the "
                         f"epochs{drawn})")
        elif cfg.model_name == "error_predictor":
            lines.append("- target |log1p(1 spp) − log1p(gold)| / its 99th percentile, clipped to [0, 1]; BCE loss"
                         + (f"; both divided first by the probe's exposure scale (its radiance's key, the "
                            f"log-average of 8×8 tile means, brought to {PROBE_KEY}; the ONNX file records it)"
                            if cfg.auto_exposure else "; no exposure step (the ONNX file records it)"))
        else:
            lines.append(f"- {self.model.layers} hidden 3×3 conv layers of {self.model.hidden} channels")
            lines.append("- input colours divided by the current frame's exposure scale (its radiance's key, the "
                         f"log-average of 8×8 tile means, brought to {CONFIDENCE_KEY}; the ONNX file records it)"
                         if cfg.auto_exposure else "- no exposure step (the ONNX file records it)")
            denoiser = self.train_set.denoiser
            lines.append(f"- input current frame: the 1-spp render denoised by `{denoiser.path}` (sha256 "
                         f"{denoiser.digest}…; the temporal pass's source, what the runtime packs)")
            lines.append("- input history: gold frame t reprojected as the runtime's temporal pass does (zero where "
                         "its depth/normal tests find no matching texel)")
            lines.append("- target: confidence that history is valid = 1 − mask, the mask being where gold frame t "
                         "warped by exact motion disagrees with gold t+1 (mean |Δlog1p| > 0.1) or comes from off "
                         "screen; class-balanced BCE; ROC AUC scores the mask against 1 − output over all pixels, "
                         "over those passing the temporal tests (tested) and for the temporal stage (failed tests "
                         "= disocclusion)")
        base_runs = self._base_runs()
        for base in base_runs:
            if base.get("onnx"):   # an exported model: its own card (when beside it) tells how it was made
                lines.append(f"- fine-tuned from the weights of `{base['path']}` (sha256 {base['onnx']}…"
                             + ("; its card follows under 'Base model')" if base.get("card") else "; no card beside it)"))
                continue
            metrics = ", ".join(f"{k[4:]} {v:.4g}" for k, v in base["metrics"].items())
            lines.append(f"- fine-tuned from `{base['path']}`: {base['epochs']} epochs, {base['seconds'] / 60:.1f} min"
                         + (f" (its last validation: {metrics})" if metrics else ""))
        base_minutes = sum(base["seconds"] for base in base_runs) / 60
        lines.append(f"- wall time: {self.seconds / 60:.1f} min"
                     + (f" (+ {base_minutes:.1f} min for the run(s) it was fine-tuned from)" if base_minutes else "")
                     + f", {self.context.describe()}")
        speed = self.throughput()
        if speed:
            lines.append(f"- throughput: {speed['steps_per_s']:.3g} steps/s, {speed['views_per_hour']:,.0f} training "
                         f"views/hour (batch {cfg.batch} × {self.context.world_size} process(es), this session; "
                         "validation and checkpoints not counted)")
        if gold < 1024:
            lines.append(f"- note: gold at {gold} spp is itself noisy, so it is a soft target and "
                         "the metrics below are against a noisy reference (a small recipe sized for a 2-core "
                         "machine; rerun examples/train_models.sh with larger VIEWS/SIZE/GOLD for better models)")
        lines += ["",
                  f"## Validation (last epoch, held-out views; every {cfg.validate_every} epoch(s) in the history)"]
        lines += [f"- {k[4:]}: {v:.4f}" for k, v in last.items() if k.startswith("val_")]
        lines += ["", "## History", "",
                  "The first epoch, every validated one and the last; train loss is the mean and step time the "
                  "sum over the epochs since the row above (the checkpoint keeps every epoch).", "",
                  "| epoch | step | spp | train loss | its steps, s | "
                  + " | ".join(k[4:] for k in last if k.startswith("val_")) + " |",
                  "|" + " --- |" * (5 + sum(k.startswith("val_") for k in last))]
        for h, since in _card_history_rows(self.history):
            loss = np.mean([row["train_loss"] for row in since])
            timed = [row["steps_seconds"] for row in since if "steps_seconds" in row]   # older runs lack it
            seconds = f"{sum(timed):.1f}" if timed else "—"
            lines.append(f"| {h['epoch']} | {h['step']} | {h['spp']} | {loss:.4f} | {seconds} | "
                         + " | ".join(f"{h[k]:.4f}" if k in h else "—" for k in last if k.startswith("val_")) + " |")
        for base in base_runs:
            if base.get("card"):
                lines += embedded_card("Base model", Path(base["path"]).with_suffix(".md").name, base["card"])
        return "\n".join(lines) + "\n"


def _card_history_rows(history: list) -> list:
    """(row shown, the rows it stands for) for a model card's history table: the first epoch, every
    validated epoch and the last, each with the epochs since the shown row before it (itself included)."""
    shown, since = [], []
    for index, row in enumerate(history):
        since.append(row)
        if index == 0 or index == len(history) - 1 or any(key.startswith("val_") for key in row):
            shown.append((row, since))
            since = []
    return shown


def _with_new_input_channels(weights: dict, expected: dict) -> dict:
    """``weights`` of an exported model whose first layer reads fewer input channels than ``expected``'s
    (a denoiser from before the sample-count plane: 10 of 11) with that layer's missing input channels
    added as zeros, so the fine-tune starts from exactly the function the base model computed."""
    first = next(name for name, tensor in expected.items() if tensor.dim() == 4)
    old, new = weights.get(first), expected[first]
    if old is None or old.ndim != 4 or old.shape[1] >= new.shape[1] or \
            (old.shape[0], *old.shape[2:]) != (new.shape[0], *new.shape[2:]):
        return weights
    padded = np.zeros(tuple(new.shape), old.dtype)
    padded[:, :old.shape[1]] = old
    return weights | {first: padded}


def _deepened(weights: dict, expected: dict) -> dict:
    """``weights`` of a U-Net with one level fewer than ``expected``'s (its widths are the first ones of
    the new network's) mapped into the deeper one so that it computes exactly the same function: each old
    up/merge stage moves one index down and the new bottom level keeps its fresh initialisation. What
    comes up from the new level starts at zero influence: a concat merge at the old bottom passes the skip
    through (identity centre taps on the skip half, zeros on the half from below; its input is post-ReLU,
    so ReLU(identity) is exact), an add merge gets a zero transposed conv. Training then decides how much
    the new level contributes. Anything else is returned as it is, for the shape check to report."""
    def levels(names):
        return len({name.split(".")[1] for name in names if name.startswith("down.")})

    new_levels = levels(expected)
    if levels(weights) != new_levels - 1 or new_levels < 3:
        return weights
    bottom_width = expected["up.0.weight"].shape[1]    # ConvTranspose2d weights: (in, out, kh, kw)
    if tuple(weights.get(f"down.{new_levels - 2}.2.weight", np.zeros(0)).shape)[:1] != (bottom_width,):
        return weights
    moved = {name: value for name, value in weights.items() if not name.startswith(("up.", "merge."))}
    for name, value in weights.items():
        if name.startswith(("up.", "merge.")):
            kind, index, rest = name.split(".", 2)
            moved[f"{kind}.{int(index) + 1}.{rest}"] = value
    for name in expected:
        if name.startswith((f"down.{new_levels - 1}.", "up.0.")):
            moved[name] = expected[name].detach().cpu().numpy()
    if "merge.0.0.weight" not in expected:      # add merge: nothing comes up until training says so
        return moved | {name: np.zeros(tuple(expected[name].shape), np.float32) for name in ("up.0.weight", "up.0.bias")}
    first = np.zeros(tuple(expected["merge.0.0.weight"].shape), np.float32)
    channels = np.arange(bottom_width)
    first[channels, bottom_width + channels, 1, 1] = 1.0     # cat([from below, skip]): the skip half
    second = np.zeros(tuple(expected["merge.0.2.weight"].shape), np.float32)
    second[channels, channels, 1, 1] = 1.0
    zeros = np.zeros(bottom_width, np.float32)
    return moved | {"merge.0.0.weight": first, "merge.0.0.bias": zeros,
                    "merge.0.2.weight": second, "merge.0.2.bias": zeros}


def base_architecture(path) -> dict:
    """The U-Net widths and bottom merge of the denoiser in ``path`` (an exported .onnx or a checkpoint), as
    {"widths": (…), "bottom_merge": "add" | "concat"}, for a fine-tune that keeps them; {} where the file is not
    such a model (the fine-tune's loading then says why)."""
    path = Path(path)
    try:
        if path.suffix.lower() == ".onnx":
            import onnx

            names = {i.name: tuple(i.dims) for i in onnx.load(str(path), load_external_data=False).graph.initializer}
        else:
            import torch

            state = torch.load(path, map_location="cpu", weights_only=False)
            names = {name: tuple(tensor.shape) for name, tensor in state["model"].items()}
    except Exception:  # onnx and torch raise many types for missing or corrupt files; loading reports them
        return {}
    levels = sorted({int(name.split(".")[1]) for name in names if re.fullmatch(r"down\.\d+\.2\.weight", name)})
    if not levels or levels != list(range(len(levels))):
        return {}
    return {"widths": tuple(names[f"down.{level}.2.weight"][0] for level in levels),
            "bottom_merge": "concat" if "merge.0.0.weight" in names else "add"}


def _level_widths(weights: dict, expected: dict) -> tuple[list | None, list]:
    """Each level's width in ``weights`` and in ``expected`` (U-Nets of the same levels and input channels),
    or None for the first where ``weights`` is not such a U-Net."""
    levels = len({name.split(".")[1] for name in expected if name.startswith("down.")})
    names = [f"down.{level}.2.weight" for level in range(levels)]
    new = [expected[name].shape[0] for name in names]
    if any(name not in weights or weights[name].ndim != 4 for name in names + ["down.0.0.weight"]) or \
            weights["down.0.0.weight"].shape[1] != expected["down.0.0.weight"].shape[1]:
        return None, new
    return [weights[name].shape[0] for name in names], new


def _narrowed(weights: dict, expected: dict) -> dict:
    """``weights`` of a U-Net with the levels of ``expected``'s but wider ones, cut down to its widths by
    keeping at each activation the channels whose filters weigh most (L1 norm; pruning to start a
    fine-tune of a cheaper network from a trained one). Every layer keeps the input channels its producer
    kept: a level's output feeds its skip, the next level down and, under an add merge, the sum with what
    comes up (whose channels are chosen by both producers' filters together); a concat merge reads the
    transposed conv's kept channels, then the skip's. A network whose dropped channels were all zero
    computes what it did. Anything else is returned as it is, for the shape check to report."""
    old, new = _level_widths(weights, expected)
    if old is None or old == new or any(n > o for n, o in zip(new, old)):
        return weights
    levels = len(new)

    def strongest(norms: np.ndarray, count: int) -> np.ndarray:
        return np.sort(np.argsort(-norms, kind="stable")[:count])

    def out_norms(name: str, transposed: bool = False) -> np.ndarray:
        value = np.abs(weights[name])
        return value.sum(axis=(0, 2, 3)) if transposed else value.sum(axis=(1, 2, 3))

    out = {}   # layer → its kept output channels
    kept_in = {}
    add_merge = "merge.0.0.weight" not in weights
    summed = levels - 2   # the level an add merge sums into
    for level in range(levels):
        out[f"down.{level}.0"] = strongest(out_norms(f"down.{level}.0.weight"), new[level])
        norms = out_norms(f"down.{level}.2.weight")
        if add_merge and level == summed:
            norms = norms + out_norms("up.0.weight", transposed=True)
        out[f"down.{level}.2"] = strongest(norms, new[level])
        kept_in[f"down.{level}.0"] = (np.arange(weights["down.0.0.weight"].shape[1]) if level == 0
                                      else out[f"down.{level - 1}.2"])
        kept_in[f"down.{level}.2"] = out[f"down.{level}.0"]
    below = out[f"down.{levels - 1}.2"]
    for j in range(levels - 1):
        level = levels - 2 - j
        kept_in[f"up.{j}"] = below
        if add_merge and j == 0:
            out["up.0"] = below = out[f"down.{level}.2"]
            continue
        out[f"up.{j}"] = strongest(out_norms(f"up.{j}.weight", transposed=True), new[level])
        kept_in[f"merge.{j}.0"] = np.concatenate([out[f"up.{j}"], old[level] + out[f"down.{level}.2"]])
        out[f"merge.{j}.0"] = strongest(out_norms(f"merge.{j}.0.weight"), new[level])
        kept_in[f"merge.{j}.2"] = out[f"merge.{j}.0"]
        out[f"merge.{j}.2"] = below = strongest(out_norms(f"merge.{j}.2.weight"), new[level])
    kept_in["head"] = below
    narrowed = dict(weights)
    for layer, inputs in kept_in.items():
        weight, bias = weights[f"{layer}.weight"], weights[f"{layer}.bias"]
        outputs = out.get(layer, np.arange(weight.shape[1 if layer.startswith("up.") else 0]))
        if layer.startswith("up."):   # ConvTranspose2d: (in, out, kh, kw)
            narrowed[f"{layer}.weight"] = weight[inputs][:, outputs]
        else:
            narrowed[f"{layer}.weight"] = weight[outputs][:, inputs]
        narrowed[f"{layer}.bias"] = bias[outputs]
    return narrowed


def _widened(weights: dict, expected: dict) -> dict:
    """``weights`` of a U-Net with the levels of ``expected``'s but narrower ones (at least one level) set
    into the wider network so that it computes exactly the same function: every old channel keeps its index
    (a concat merge's skip half starts at the new width), a new channel's own filters keep their fresh
    initialisation, and every filter's taps on a new input channel start at zero, so nothing reads the new
    channels until training gives them weight (those taps get a gradient at once: the new channels are
    not zero). Anything else is returned as it is, for the shape check to report."""
    old, new = _level_widths(weights, expected)
    if old is None or old == new or any(n < o for n, o in zip(new, old)):
        return weights
    levels, inputs = len(new), weights["down.0.0.weight"].shape[1]
    read = {}    # layer → where its old input channels sit in the new input
    for level in range(levels):
        read[f"down.{level}.0"] = np.arange(inputs if level == 0 else old[level - 1])
        read[f"down.{level}.2"] = np.arange(old[level])
    for j in range(levels - 1):
        level = levels - 2 - j
        read[f"up.{j}"] = np.arange(old[level + 1])
        if f"merge.{j}.0.weight" in expected:      # cat([from below, skip])
            read[f"merge.{j}.0"] = np.concatenate([np.arange(old[level]), new[level] + np.arange(old[level])])
            read[f"merge.{j}.2"] = np.arange(old[level])
    read["head"] = np.arange(old[0])
    widened = dict(weights)
    for layer, positions in read.items():
        if f"{layer}.weight" not in weights or f"{layer}.bias" not in weights:
            return weights
        weight, bias = weights[f"{layer}.weight"], weights[f"{layer}.bias"]
        fresh = expected[f"{layer}.weight"].detach().cpu().numpy().copy()
        fresh_bias = expected[f"{layer}.bias"].detach().cpu().numpy().copy()
        if weight.ndim != 4:
            return weights
        transposed = layer.startswith("up.")      # ConvTranspose2d: (in, out, kh, kw)
        if transposed:
            fresh = fresh.transpose(1, 0, 2, 3)
            weight = weight.transpose(1, 0, 2, 3)
        if weight.shape[1] != len(positions) or fresh.shape[0] < weight.shape[0] or \
                fresh.shape[1] <= positions.max(initial=-1):
            return weights
        unread = np.setdiff1d(np.arange(fresh.shape[1]), positions)
        fresh[:, unread] = 0.0
        fresh[np.ix_(np.arange(weight.shape[0]), positions)] = weight
        fresh_bias[:bias.shape[0]] = bias
        widened[f"{layer}.weight"] = fresh.transpose(1, 0, 2, 3) if transposed else fresh
        widened[f"{layer}.bias"] = fresh_bias
    return widened


def train(config: TrainConfig, progress: bool = True) -> dict | None:
    """Train, export ``OUT/<name>.onnx`` + model card; returns {"onnx", "card", "metrics", "seconds"} (on
    rank 0; None on the other data-parallel ranks, which write nothing)."""
    trainer = Trainer(config, progress)
    try:
        metrics = trainer.run()
        if not trainer.context.main:
            return None
        onnx_path, card = trainer.export()
    finally:
        trainer.context.close()
    return {"onnx": str(onnx_path), "card": str(card), "metrics": metrics, "seconds": trainer.seconds}


# What a dataset's albedo planes held before each change of the renderer's convention
# (trace_pass.GUIDE_ALBEDO), by the version that changed it
GUIDE_ALBEDO_CHANGES = {2: "escaping paths with albedo 0",
                        3: "emitters with their reflectance as albedo, 0 for a black lamp",
                        4: "the albedo through mirrors and glass untinted by their colour"}


def _older_guide_albedo(version: int) -> str:
    """The model card's words for a dataset rendered under guide albedo ``version`` (none for today's)."""
    notes = [text for changed_in, text in GUIDE_ALBEDO_CHANGES.items() if version < changed_in]
    return f"{'; '.join(notes)} (rendered before the guide albedo's version {version + 1}); " if notes else ""
