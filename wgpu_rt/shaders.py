"""Loading and composing WGSL.

Shaders live as ``.wgsl`` files in the resource packages ``wgpu_rt.wgsl`` (path tracing) and
``wgpu_rt.nn_kernels`` (networks) and are read through importlib.resources, so an installed wheel
works outside the source tree. WGSL has no include, so a kernel names the modules it needs with a
line ``// #import name.wgsl``; ``compose`` splices each module in once (depth first, so a module's own
imports come before it). Specialization uses WGSL ``override`` constants where they reach and
``#define``-free text substitution (``{{NAME}}``) where they cannot (array sizes, workgroup sizes
used in ``var<workgroup>`` declarations, types).
"""

from __future__ import annotations

import re
from functools import lru_cache
from importlib import resources

PATH_TRACING = "wgpu_rt.wgsl"
NN_KERNELS = "wgpu_rt.nn_kernels"

_IMPORT = re.compile(r"^\s*//\s*#import\s+(\S+)\s*$", re.MULTILINE)
_PLACEHOLDER = re.compile(r"\{\{(\w+)\}\}")


@lru_cache(maxsize=None)
def read_wgsl(name: str, package: str = PATH_TRACING) -> str:
    """The text of one ``.wgsl`` file of ``package``."""
    return resources.files(package).joinpath(name).read_text(encoding="utf-8")


def list_wgsl(package: str = PATH_TRACING) -> list[str]:
    """Names of every ``.wgsl`` file in ``package`` (used by the shader-validation tests)."""
    return sorted(p.name for p in resources.files(package).iterdir() if p.name.endswith(".wgsl"))


def compose(name: str, package: str = PATH_TRACING, substitutions: dict | None = None,
            replacements: dict | None = None) -> str:
    """``name`` with its ``// #import`` lines resolved and ``{{KEY}}`` placeholders substituted.
    ``replacements`` maps an imported module's name to another module spliced in its place (a kernel
    variant picks one of two implementations of the same functions)."""
    seen: set[str] = set()
    swaps = replacements or {}

    def expand(module: str) -> str:
        module = swaps.get(module, module)
        if module in seen:
            return ""
        seen.add(module)
        source = read_wgsl(module, package)
        return _IMPORT.sub(lambda m: expand(m.group(1)), source)

    text = expand(name)
    subs = substitutions or {}

    def substitute(match: re.Match) -> str:
        key = match.group(1)
        if key not in subs:
            raise KeyError(f"{package}/{name}: no value given for placeholder {{{{{key}}}}}")
        return str(subs[key])

    return _PLACEHOLDER.sub(substitute, text)
