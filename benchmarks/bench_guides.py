"""The denoiser with the guides another renderer gives: no depth plane, or normals in camera space.

Many renderers write the inputs Intel OIDN takes and no depth; `wgpu-rt denoise` and `wgpu_rt.denoise` then read
one distance everywhere. Others write normals in camera space, where ours are in world space. Each scene is rendered
at ``--spp`` (seeds 7, 8, …; the aux pass's albedo) and denoised through ``wgpu_rt.denoise`` with its guides as
rendered, with no depth (``depth=None``: every pixel a surface at one distance), with only where a surface was hit
(1 there, 0 where paths escaped, as an alpha channel would give), and with its normals turned into the camera's frame
(x right, y up, z toward the viewer). Printed: PSNR (x/(1+x), gamma 2.2) against the gold, the mean of the seeds,
per scene and spp, and the means.

    python3 benchmarks/bench_guides.py --scenes cornell sun-room --gold-renderer mitsuba --gold-cache /tmp/gold
"""

from __future__ import annotations

import argparse

import numpy as np
from common import add_gold_arguments, gold_render, image_size, load_scenes, print_header

WAYS = ("as given", "no depth", "hit mask", "camera normals")


def camera_frame(camera) -> np.ndarray:
    """The rotation from world space into the camera's frame (x right, y up, z toward the viewer)."""
    forward = (camera.target - camera.origin) / np.linalg.norm(camera.target - camera.origin)
    right = np.cross(forward, camera.up) / np.linalg.norm(np.cross(forward, camera.up))
    return np.stack([right, np.cross(right, forward), -forward]).astype(np.float32)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scenes", nargs="+", default=["cornell", "cornell-glossy", "sun-room", "painted"])
    parser.add_argument("--size", type=image_size, default=(256, 256))
    parser.add_argument("--spp", type=int, nargs="+", default=[1, 4])
    parser.add_argument("--seeds", type=int, default=2, help="noisy renders per row (seeds 7, 8, …)")
    parser.add_argument("--max-depth", type=int, default=8)
    add_gold_arguments(parser, 4096)
    args = parser.parse_args()

    import wgpu_rt
    from wgpu_rt.metrics import psnr

    print_header(args)
    print(f"\nPSNR (dB) against {args.gold_spp}-spp gold, {args.size[0]}×{args.size[1]}, mean of {args.seeds} seeds")
    print(f"{'scene':<18} {'spp':>4} " + " ".join(f"{way:>14}" for way in WAYS))
    totals = {(spp, way): [] for spp in args.spp for way in WAYS}
    for scene in load_scenes(args.scenes):
        gold = gold_render(scene, args.size, args)
        for spp in args.spp:
            scores = {way: [] for way in WAYS}
            for seed in range(7, 7 + args.seeds):
                frame = wgpu_rt.render(scene, spp=spp, size=args.size, seed=seed, max_depth=args.max_depth,
                                       aux_samples=4, aovs=("albedo", "normal", "depth"))
                depth, normal = frame.aovs["depth"], frame.aovs["normal"]
                given = {"as given": (normal, depth), "no depth": (normal, None),
                         "hit mask": (normal, (depth > 0).astype(np.float32)),
                         "camera normals": (normal @ camera_frame(scene.camera).T, depth)}
                for way in WAYS:
                    clean = wgpu_rt.denoise(frame.color, frame.aovs["albedo"], *given[way], spp, albedo_samples=0)
                    scores[way].append(psnr(gold, clean))
            for way in WAYS:
                totals[spp, way].append(np.mean(scores[way]))
            print(f"{scene.name:<18} {spp:>4} " + " ".join(f"{np.mean(scores[way]):>14.2f}" for way in WAYS),
                  flush=True)
    for spp in args.spp:
        print(f"{'mean':<18} {spp:>4} " + " ".join(f"{np.mean(totals[spp, way]):>14.2f}" for way in WAYS))


if __name__ == "__main__":
    main()
