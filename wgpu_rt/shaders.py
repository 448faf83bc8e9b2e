"""Loading and composing WGSL.

Shaders live as ``.wgsl`` files in the resource packages ``wgpu_rt.wgsl`` (path tracing, one subfolder
per stage: ``accel/``, ``trace/``, ``frame/``) and ``wgpu_rt.nn_kernels`` (networks) and are read
through importlib.resources, so an installed wheel works outside the source tree; a benchmark or test
passes its own folder (a ``Path``) for shaders that do not ship. WGSL has no include, so a kernel names
the modules it needs with a line ``// #import stage/name.wgsl`` (relative to its package); ``compose`` splices each module in once (depth first, so a module's own
imports come before it). Specialization uses WGSL ``override`` constants where they reach and
``#define``-free text substitution (``{{NAME}}``) where they cannot (array sizes, workgroup sizes
used in ``var<workgroup>`` declarations, types).
"""

from __future__ import annotations

import re
from functools import lru_cache
from importlib import resources
from pathlib import Path

PATH_TRACING = "wgpu_rt.wgsl"
NN_KERNELS = "wgpu_rt.nn_kernels"

_IMPORT = re.compile(r"^\s*//\s*#import\s+(\S+)\s*$", re.MULTILINE)
_PLACEHOLDER = re.compile(r"\{\{(\w+)\}\}")


@lru_cache(maxsize=None)
def read_wgsl(name: str, package: str | Path = PATH_TRACING) -> str:
    """The text of one ``.wgsl`` file (``stage/name.wgsl``) of ``package``."""
    return _root(package).joinpath(name).read_text(encoding="utf-8")


def list_wgsl(package: str | Path = PATH_TRACING) -> list[str]:
    """Paths (``stage/name.wgsl``) of every ``.wgsl`` file in ``package`` (for the shader-validation tests)."""
    def walk(folder, prefix: str):
        for entry in folder.iterdir():
            if entry.is_dir():
                yield from walk(entry, f"{prefix}{entry.name}/")
            elif entry.name.endswith(".wgsl"):
                yield prefix + entry.name

    return sorted(walk(_root(package), ""))


def _root(package: str | Path):
    return package if isinstance(package, Path) else resources.files(package)


def compose(name: str, package: str | Path = PATH_TRACING, substitutions: dict | None = None,
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
