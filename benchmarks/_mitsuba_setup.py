"""Pick Mitsuba's fastest CPU variant for the benchmarks: llvm_ad_rgb when Debian's LLVM 19 is
installed (`apt-get install -y libllvm19`; LLVM 15 crashes Dr.Jit), else scalar_rgb."""

import os
from pathlib import Path

LLVM19 = Path("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1")


def mitsuba(prefer_llvm: bool = True):
    if prefer_llvm and LLVM19.exists():
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", str(LLVM19))
    import mitsuba as mi

    variant = "llvm_ad_rgb" if prefer_llvm and LLVM19.exists() else "scalar_rgb"
    mi.set_variant(variant)
    return mi


def render_mitsuba(mi, scene, size, spp, max_depth, seed=0):
    import numpy as np

    from wgpu_rt.scene.mitsuba import to_mitsuba

    loaded = mi.load_dict(to_mitsuba(scene, size[0], size[1], spp, max_depth, seed=seed))
    return np.array(mi.render(loaded, spp=spp, seed=seed))[..., :3]
