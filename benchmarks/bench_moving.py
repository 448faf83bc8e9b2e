"""Per-frame cost of a moving object: the `mesh` scene with the Stanford bunny (../shared/meshes) sliding
across the room for N frames, against the same scene standing still, each rendered through one
Renderer (its set-up and first two frames are not timed: they compile kernels and build the BVHs),
in the order static, moving, moving, static.
The last column is moving over static per frame (issue 13: ≤ 1.5 on lavapipe, goal 1.05).
``--scene moving``: the built-in `moving` instead (its box slides and turns; static: the box held
still, the camera moving in both).

    python3 benchmarks/bench_moving.py [--frames 40] [--size 64] [--spp 1] [--denoise] [--scene bunny]
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np
from common import BUNNY, print_header

from wgpu_rt.renderer import Renderer
from wgpu_rt.scene import load_scene
from wgpu_rt.scene.transforms import compose, translate

SLIDE = 0.6      # the bunny travels from x = -SLIDE/2 to +SLIDE/2


def builtin_scene(name: str, frames: int, moving: bool):
    """The built-in ``name`` over ``frames`` frames; not ``moving``: its meshes hold their first pose."""
    scene = load_scene(name)
    scene.frame_count = frames
    if not moving:
        for mesh in scene.meshes:
            mesh.keyframes = {}
    return scene


def bunny_scene(frames: int, moving: bool):
    """The mesh scene with the bunny; ``moving``: keyframed to slide along x over ``frames`` frames."""
    scene = load_scene("mesh", mesh=BUNNY)
    scene.frame_count = frames
    if moving:
        bunny = scene.meshes[-1]
        for frame in range(frames):
            offset = SLIDE * (frame / max(frames - 1, 1) - 0.5)
            bunny.keyframes[frame] = compose(translate([offset, 0.0, 0.0]), bunny.transform)
    return scene


WARM_UP_FRAMES = 2   # the set-up, and the first moving frame (it builds the two-level geometry)


def seconds_per_frame(scene, frames: int, **options) -> float:
    """Mean wall time per frame of ``scene`` after WARM_UP_FRAMES."""
    stream = Renderer(scene, **options).frames(range(frames))
    for _ in range(WARM_UP_FRAMES):
        next(stream)
    started = time.perf_counter()
    count = sum(1 for _ in stream)
    return (time.perf_counter() - started) / count


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--size", type=int, default=64)
    parser.add_argument("--spp", type=int, default=1)
    parser.add_argument("--denoise", action="store_true")
    parser.add_argument("--scene", default="bunny", help="bunny, or a built-in scene with moving meshes")
    args = parser.parse_args()
    print_header(args)
    if args.scene == "bunny" and not BUNNY.exists():
        print(f"{BUNNY} is missing: nothing to measure")
        return 1
    options = dict(spp=args.spp, size=(args.size, args.size), denoise=args.denoise, aovs=())
    make = bunny_scene if args.scene == "bunny" else lambda *a, **k: builtin_scene(args.scene, *a, **k)
    # Static, moving, moving, static: a drift in the machine's load weighs on both alike.
    times = {True: [], False: []}
    for moves in (False, True, True, False):
        times[moves].append(seconds_per_frame(make(args.frames, moving=moves), args.frames, **options))
    static, moving = np.mean(times[False]), np.mean(times[True])
    print(f"{args.scene} {args.size}x{args.size} {args.spp} spp, {args.frames} frames"
          f"{', denoised' if args.denoise else ''}: static {static * 1e3:.1f} ms/frame, "
          f"moving {moving * 1e3:.1f} ms/frame, moving/static {moving / static:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
