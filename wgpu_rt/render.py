"""``render()``: one frame of a scene, path traced on the GPU, as numpy arrays.

Samples are added in batches of whole-frame passes, one submit per batch, so a progress bar can follow
and no command buffer holds seconds of work; every batch continues each pixel's sample sequence, so
the result is the same whatever the batching (and the same bit for bit for the same seed).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .errors import WgpuRtError

AOV_CHANNELS = {"albedo": 3, "normal": 3, "depth": 1, "motion": 2, "spp": 1}
DEFAULT_AOVS = ("albedo", "normal", "depth", "motion", "spp")
SAMPLES_PER_SUBMIT = 1 << 21   # pixel samples per command buffer (a fraction of a second on lavapipe)


@dataclass
class RenderResult:
    color: np.ndarray                              # (H, W, 3) float32 linear radiance
    aovs: dict[str, np.ndarray] = field(default_factory=dict)   # name → (H, W, C) float32
    seconds: float = 0.0                           # tracing time, submit to readback (no compile)
    setup_seconds: float = 0.0                     # scene flattening, BVH build and kernel compile
    samples: int = 0                               # pixel samples taken

    @property
    def samples_per_second(self) -> float:
        return self.samples / self.seconds if self.seconds > 0 else 0.0


def parse_size(size) -> tuple[int, int]:
    if isinstance(size, str):
        try:
            width, height = (int(v) for v in size.lower().split("x"))
        except ValueError:
            raise WgpuRtError(f"size {size!r}: expected WIDTHxHEIGHT, e.g. 256x256") from None
    else:
        width, height = size
    if not (1 <= width <= 16384 and 1 <= height <= 16384):
        raise WgpuRtError(f"size {width}x{height}: width and height must be in 1..16384")
    return int(width), int(height)


def check_aovs(aovs) -> tuple[str, ...]:
    unknown = [a for a in aovs if a not in AOV_CHANNELS]
    if unknown:
        raise WgpuRtError(f"unknown AOV {unknown[0]!r}; choose from {', '.join(AOV_CHANNELS)}")
    return tuple(aovs)


def render(scene, spp: int = 16, size=(256, 256), max_depth: int = 8, seed: int = 0, frame: int = 0,
           aovs=DEFAULT_AOVS, progress: bool = False, mesh=None) -> RenderResult:
    """Path trace ``frame`` of ``scene`` (a Scene, a built-in name or a scene-file path) at ``spp``
    samples per pixel; ``size`` is (width, height) or "WxH"."""
    from .gpu import get_context
    from .passes import FrameBuffers
    from .scene import load_scene
    from .accel.geometry import GeometryBuffers
    from .trace import SceneFeatures, TracePass

    width, height = parse_size(size)
    aovs = check_aovs(aovs)
    if int(spp) < 1:
        raise WgpuRtError(f"spp must be at least 1, got {spp}")
    if int(max_depth) < 1:
        raise WgpuRtError(f"max_depth must be at least 1, got {max_depth}")
    if not 0 <= int(seed) < 2 ** 32:
        raise WgpuRtError(f"seed must be in 0..2^32-1, got {seed}")

    started = time.perf_counter()
    scene = load_scene(scene, mesh=mesh)
    ctx = get_context()
    geometry = GeometryBuffers.build(scene, frame)
    features = SceneFeatures.of(scene, write_aovs=any(a != "spp" for a in aovs))
    trace = TracePass(ctx, scene, geometry, width, height, frame=frame, max_depth=int(max_depth),
                      seed=int(seed), features=features)
    buffers = FrameBuffers(ctx, width, height)
    setup = time.perf_counter() - started

    started = time.perf_counter()
    per_submit = max(trace.chunk_size, SAMPLES_PER_SUBMIT // (width * height) // trace.chunk_size * trace.chunk_size)
    bar = _progress_bar(spp, scene.name, progress)
    done = 0
    while done < spp:
        batch = min(per_submit, spp - done)
        trace.schedule.samples = batch
        encoder = ctx.device.create_command_encoder(label="render")
        if done == 0:
            trace.clear(encoder, buffers)
        trace.execute(encoder, buffers)
        ctx.device.queue.submit([encoder.finish()])
        done += batch
        if bar is not None:
            ctx.read(buffers["spp"], np.uint32, nbytes=4)  # waits for the batch, so the bar tells time
            bar.update(batch)
    color = _hwc(buffers.read("radiance"))
    outputs = {name: _hwc(buffers.read(name)).astype(np.float32) for name in aovs}
    seconds = time.perf_counter() - started
    if bar is not None:
        bar.close()
    return RenderResult(color, outputs, seconds, setup, spp * width * height)


def _hwc(planes: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(np.transpose(planes, (1, 2, 0)))


def _progress_bar(total: int, name: str, enabled: bool):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="spp", desc=f"render {name}", leave=False)
