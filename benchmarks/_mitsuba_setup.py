"""Mitsuba 3 in the fastest variant this machine has, for the benchmarks that put it beside us:
cuda_ad_rgb where Dr.Jit finds a CUDA GPU, else llvm_ad_rgb when Debian's LLVM 19 is installed
(`apt-get install -y libllvm19`; LLVM 15 crashes Dr.Jit) or DRJIT_LIBLLVM_PATH names an LLVM, else
scalar_rgb."""

import os
import time
from pathlib import Path

LLVM19 = Path("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1")


def variant_choice() -> tuple[str, list[str]]:
    """(the fastest variant here, a "Mitsuba VARIANT: skipped (why)" line for each faster one that is
    not). Imports drjit and mitsuba, pointing Dr.Jit at LLVM 19 first unless DRJIT_LIBLLVM_PATH is set."""
    if LLVM19.exists():
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", str(LLVM19))
    import drjit as dr
    import mitsuba as mi

    skipped = []
    if "cuda_ad_rgb" not in mi.variants():
        skipped.append("Mitsuba cuda_ad_rgb: skipped (this Mitsuba build has no CUDA variants)")
    elif not dr.has_backend(dr.JitBackend.CUDA):
        skipped.append("Mitsuba cuda_ad_rgb: skipped (Dr.Jit finds no CUDA device)")
    else:
        return "cuda_ad_rgb", skipped
    if "DRJIT_LIBLLVM_PATH" in os.environ:
        return "llvm_ad_rgb", skipped
    skipped.append(f"Mitsuba llvm_ad_rgb: skipped (no LLVM 19 at {LLVM19} and DRJIT_LIBLLVM_PATH unset; "
                   "apt-get install -y libllvm19)")
    return "scalar_rgb", skipped


def mitsuba(variant: str | None = None):
    """The mitsuba module set to ``variant`` (default: ``variant_choice``'s)."""
    if variant is None:
        variant = variant_choice()[0]
    import mitsuba as mi

    mi.set_variant(variant)
    return mi


def timed_render(mi, scene, size, spp: int, max_depth: int, seed: int = 0, frame: int = 0):
    """(image (H, W, 3) float32, seconds) of Mitsuba's path tracer on our ``scene`` at ``frame``; the scene
    load is not timed, the copy of the image to numpy (which waits for the JIT variants' kernels) is."""
    import numpy as np

    from wgpu_rt.scene.mitsuba import to_mitsuba

    loaded = mi.load_dict(to_mitsuba(scene, size[0], size[1], spp, max_depth, frame, seed=seed))
    started = time.perf_counter()
    image = np.array(mi.render(loaded, spp=spp, seed=seed), np.float32)[..., :3]
    return image, time.perf_counter() - started


def render_mitsuba(mi, scene, size, spp: int, max_depth: int, seed: int = 0):
    """The image of ``timed_render``."""
    return timed_render(mi, scene, size, spp, max_depth, seed)[0]
