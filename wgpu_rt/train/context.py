"""Where training runs: the torch device, mixed precision, and the data-parallel group, built in one place.

``training_context(device)`` picks ``cuda`` or ``cpu`` (``auto``: CUDA when torch sees it). On CUDA the
packed training frames are kept in GPU memory (built once; crops and augmentation are tensor ops there),
the model runs under ``torch.autocast`` in bfloat16 (float16 with a GradScaler where the GPU lacks bf16)
and cuDNN picks kernels by its heuristics; on the CPU everything stays float32 and frames are kept packed as
they are first drawn, up to a quarter of the machine's memory (the rest are packed at each draw).

Launched by ``torchrun`` (WORLD_SIZE, RANK, LOCAL_RANK in the environment), every process joins one
process group (NCCL on CUDA, gloo on the CPU) and the model is wrapped in DistributedDataParallel, so
gradients are averaged across processes after each step and the replicas stay identical. Each process
trains on its own share of every epoch's samples (``shard``); only rank 0 (``main``) writes checkpoints,
the ONNX and its card, and shows progress.
"""

from __future__ import annotations

import contextlib
import os
import sys
from dataclasses import dataclass

import numpy as np
import torch

from ..errors import WgpuRtError

DEVICES = ("auto", "cuda", "cpu")
HOST_SHARE = 0.25   # of the machine's memory, what a CPU run's processes may keep of packed frames together


@dataclass
class TrainContext:
    device: torch.device
    rank: int = 0
    world_size: int = 1
    amp_dtype: torch.dtype | None = None     # autocast dtype; None: float32 throughout
    keep_data: bool = False                  # keep the packed training frames on the device (a GPU's memory)
    # how the weights and batches are laid out: channels last, the layout of cuDNN's tensor-core
    # convolutions in half precision (NCHW makes it transpose around every conv) and of oneDNN's faster
    # CPU convolutions
    memory_format: torch.memory_format = torch.channels_last
    # bytes of packed training frames a CPU run keeps in memory as they are first drawn (None: none; the
    # others are packed again at every draw). With the two above, 1.5× the CPU's steps/s (BENCHMARKS.md §24)
    host_budget: int | None = None

    def __post_init__(self):
        self.scaler = torch.amp.GradScaler(self.device.type, enabled=self.amp_dtype == torch.float16)

    @property
    def main(self) -> bool:
        return self.rank == 0

    @property
    def distributed(self) -> bool:
        return self.world_size > 1

    def autocast(self):
        if self.amp_dtype is None:
            return contextlib.nullcontext()
        return torch.autocast(self.device.type, dtype=self.amp_dtype)

    def wrap(self, model: torch.nn.Module) -> torch.nn.Module:
        """``model`` as trained, in ``memory_format`` (in place): replicated across the group under DDP
        (which copies rank 0's initial weights to every process), else itself."""
        model.to(memory_format=self.memory_format)
        if not self.distributed:
            return model
        from torch.nn.parallel import DistributedDataParallel

        device_ids = [self.device.index] if self.device.type == "cuda" else None
        return DistributedDataParallel(model, device_ids=device_ids)

    def shard(self, order: np.ndarray) -> np.ndarray:
        """This process's part of an epoch's sample ``order`` (the same on every process): every
        ``world_size``-th item from ``rank``, the order wrapped round to equal lengths (every process must
        take the same number of steps, as with torch's DistributedSampler)."""
        if not self.distributed:
            return order
        padded = np.resize(order, -(-len(order) // self.world_size) * self.world_size)
        return padded[self.rank::self.world_size]

    def broadcast(self, value):
        """Rank 0's ``value`` on every process."""
        if not self.distributed:
            return value
        box = [value]
        torch.distributed.broadcast_object_list(box, src=0)
        return box[0]

    def gather(self, value) -> list:
        """Every process's ``value``, by rank."""
        if not self.distributed:
            return [value]
        values = [None] * self.world_size
        torch.distributed.all_gather_object(values, value)
        return values

    def mean_each(self, values: torch.Tensor) -> np.ndarray:
        """The mean over the processes of each element of ``values`` (each process's losses differ; all
        must agree on them, e.g. to stop together when one is NaN), on the host."""
        values = values.detach().float()
        if self.distributed:
            torch.distributed.all_reduce(values)
            values = values / self.world_size
        return values.cpu().numpy()

    def describe(self) -> str:
        """The hardware for the model card."""
        if self.device.type == "cuda":
            what = f"CUDA torch on {torch.cuda.get_device_name(self.device)}, {self.amp_dtype} autocast"
        else:
            what = f"CPU torch with {torch.get_num_threads()} thread(s) on a {os.cpu_count()}-core machine"
        return what + (f", {self.world_size} data-parallel processes" if self.distributed else "")

    def close(self) -> None:
        """Leave the process group together: a rank that tears its gloo connections down while another
        is still writing the model may abort in gloo's threads (about one run in four on 2 cores)."""
        if self.distributed and torch.distributed.is_initialized():
            torch.distributed.barrier()
            torch.distributed.destroy_process_group()


def resolve_device(name: str) -> torch.device:
    """``name`` (one of DEVICES) as a torch device; a clear error for ``cuda`` where torch sees none."""
    if name not in DEVICES:
        raise WgpuRtError(f"--device must be one of {', '.join(DEVICES)}, not {name!r}")
    if name == "cuda" and not torch.cuda.is_available():
        raise WgpuRtError(f"--device cuda: torch {torch.__version__} sees no CUDA device here "
                          "(use --device cpu or auto)")
    return torch.device("cuda" if name != "cpu" and torch.cuda.is_available() else "cpu")


def end_data_parallel_process(status: int) -> None:
    """Under torchrun (WORLD_SIZE > 1), end this process now with ``status``, its output flushed, without the
    interpreter's teardown; otherwise return. With its gloo group destroyed and every file written, that
    teardown still aborted one of the two processes in about one run in fifty on torch 2.13 (2 cores, two runs
    at a time: 2 of 120 with DistributedDataParallel, 6 of 280 with a plain all_reduce in its place, "terminate
    called without an active exception" with no Python frame left; none of 180 runs that ended here), and
    torchrun reports such a run as failed."""
    if _launch_env()[0] > 1:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)


def _launch_env() -> tuple[int, int, int]:
    """(world size, rank, local rank) as torchrun sets them; (1, 0, 0) when not launched by it."""
    try:
        return tuple(int(os.environ.get(key, default)) for key, default in
                     (("WORLD_SIZE", 1), ("RANK", 0), ("LOCAL_RANK", 0)))
    except ValueError as err:
        raise WgpuRtError(f"WORLD_SIZE/RANK/LOCAL_RANK must be integers ({err})") from None


def training_context(device: str = "auto") -> TrainContext:
    """The context for this process: device, precision and (under torchrun) the process group."""
    device_type = resolve_device(device).type
    world_size, rank, local_rank = _launch_env()
    torch_device = torch.device("cuda", local_rank) if device_type == "cuda" else torch.device("cpu")
    amp_dtype = None
    if device_type == "cuda":
        torch.cuda.set_device(torch_device)
        # cuDNN's heuristics, not its benchmark mode: crops vary in size and batch, and on the H200 each new
        # shape spent 2-4 s re-tuning (BENCHMARKS.md §25, ~10 shapes a run), while the U-Net's own work
        # was a few percent of a step; tuning pays back only over runs of tens of minutes (§26)
        torch.backends.cudnn.benchmark = False
        amp_dtype = torch.bfloat16 if torch.cuda.is_bf16_supported() else torch.float16
    if world_size > 1 and not torch.distributed.is_initialized():
        torch.distributed.init_process_group("nccl" if device_type == "cuda" else "gloo",
                                             rank=rank, world_size=world_size)
    on_cuda = device_type == "cuda"
    return TrainContext(torch_device, rank, world_size, amp_dtype, keep_data=on_cuda,
                        host_budget=None if on_cuda else int(physical_memory() * HOST_SHARE / world_size))


def physical_memory() -> int:
    """Bytes of memory this machine has (Linux, macOS); a conservative 4 GiB where it cannot tell."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 4 << 30
