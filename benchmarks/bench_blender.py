"""Denoising Blender's EXR: Cycles renders scenes built in Blender (benchmarks/blender_scenes.py) at a few spp
to the multilayer EXR a Blender user has (Combined plus the Denoising Data passes); `wgpu-rt denoise FILE`
denoises it with no flags (the passes and the sample count are found in the file); OIDN balanced the same
Combined, Denoising Albedo and Denoising Normal, and OIDN as Blender's own denoiser runs it by default (quality
high, the albedo and normal prefiltered: "Accurate"); PSNR (x/(1+x), gamma 2.2) against Cycles' own gold.

Blender runs in a Python of its own that imports bpy (`python3 -m venv /tmp/bpy && /tmp/bpy/bin/pip install
bpy`; bpy 5.0.1 was measured):

    python3 benchmarks/bench_blender.py --blender-python /tmp/bpy/bin/python --size 256 --spp 1 4 --seeds 2 \
        --gold-spp 4096 --gold-cache /tmp/gold
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from common import (add_model_arguments, denoise_exr, errors, oidn, parse_with_quick_defaults, print_header,
                    print_table, resolve_models)
from peers import oidn_prefiltered

SCENES_SCRIPT = Path(__file__).with_name("blender_scenes.py")
SCENES = ("glass-monkey", "dark-room", "sun-metals", "textured-studio")
GOLD_SEED = 1
VIEW_LAYER = "ViewLayer"   # the view layer of a new Blender scene


def cycles_exr(args, scene: str, spp: int, seed: int, path: Path) -> dict:
    """Cycles' render of ``scene`` as Blender writes it, read back by wgpu-rt's reader."""
    from wgpu_rt.io import read_exr

    if not path.is_file():
        command = [args.blender_python, str(SCENES_SCRIPT), scene, str(spp), str(seed), str(path),
                   "--size", str(args.size), "--threads", str(args.threads)]
        done = subprocess.run(command, capture_output=True, text=True)
        if done.returncode or not path.is_file():
            raise SystemExit(f"Blender failed on {scene} ({' '.join(command)}):\n{done.stderr[-2000:]}")
    return read_exr(path)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blender-python", required=True, metavar="PYTHON",
                        help="a Python that imports bpy (Blender as a module)")
    parser.add_argument("--scenes", nargs="+", choices=SCENES, default=list(SCENES))
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--spp", type=int, nargs="+", default=[1, 4])
    parser.add_argument("--seeds", type=int, default=1, help="noisy renders per row (seeds 7, 8, …); mean PSNR")
    parser.add_argument("--gold-spp", type=int, default=4096)
    parser.add_argument("--gold-cache", metavar="DIR", help="keep Cycles' gold EXRs here between runs")
    parser.add_argument("--threads", type=int, default=0, help="Cycles' render threads (0: all)")
    add_model_arguments(parser)
    args = parse_with_quick_defaults(parser, {"size": 48, "spp": [1, 4], "gold_spp": 64})
    check = subprocess.run([args.blender_python, "-c", "import bpy; print(bpy.app.version_string)"],
                           capture_output=True, text=True)
    if check.returncode:
        sys.exit(f"--blender-python {args.blender_python}: cannot import bpy ({check.stderr.strip()[-300:]})")
    resolve_models(args)
    print_header(args)
    print(f"Blender {check.stdout.strip()} (Cycles, CPU)")
    combined, albedo, normal = (f"{VIEW_LAYER}.{name}" for name in ("Combined", "Denoising Albedo", "Denoising Normal"))
    names = ["Cycles, noisy", "ours on Blender's EXR", "OIDN balanced on it", "OIDN as Blender runs it"]
    rows = []
    with tempfile.TemporaryDirectory(prefix="wgpu-rt-blender-") as folder:
        gold_folder = Path(args.gold_cache or folder)
        gold_folder.mkdir(parents=True, exist_ok=True)
        for scene in args.scenes:
            gold_path = gold_folder / f"blender-{scene}_{args.size}x{args.size}_{args.gold_spp}spp.exr"
            gold = cycles_exr(args, scene, args.gold_spp, GOLD_SEED, gold_path)[combined][..., :3]
            for spp in args.spp:
                scores = {name: [] for name in names}
                for seed in range(7, 7 + args.seeds):
                    path = Path(folder) / f"{scene}_{spp}_{seed}.exr"
                    layers = cycles_exr(args, scene, spp, seed, path)
                    planes = (layers[combined][..., :3], layers[albedo], layers[normal])
                    images = [planes[0], denoise_exr(path, path.with_suffix(".out.exr"), args)[combined][..., :3],
                              oidn(*planes, "balanced"), oidn_prefiltered(*planes, "high")]
                    for name, image in zip(names, images):
                        scores[name].append(errors(gold, image)["PSNR"])
                psnr = [float(np.mean(scores[name])) for name in names]
                rows.append([scene, spp, *psnr, psnr[1] - psnr[2], psnr[1] - psnr[3]])
    means = [float(np.mean([row[i] for row in rows if row[1] == spp])) for spp in args.spp for i in range(2, 8)]
    rows += [["mean", spp, *means[6 * k:6 * k + 6]] for k, spp in enumerate(args.spp)]
    print_table(f"PSNR (dB) against Cycles' {args.gold_spp}-spp gold, {args.size}², mean of {args.seeds} seed(s)",
                ["scene", "spp", *names, "ours − OIDN balanced", "ours − Blender's"], rows)


if __name__ == "__main__":
    main()
