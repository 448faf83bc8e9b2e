"""Choices made per adapter by measurement and remembered: which variant of something (a convolution
kernel, wgpu_rt.nn.autotune; a BVH node layout, wgpu_rt.trace.bvh_choice) runs fastest here.

Each choice is timed once and kept in one JSON cache keyed by whatever the caller says decides it (the
adapter and driver always: ``MeasuredChoices.adapter``), at ``$WGPU_RT_CACHE_DIR/autotune.json`` where
that is set, else ``$XDG_CACHE_HOME/wgpu-rt/autotune.json`` (``~/.cache/wgpu-rt/autotune.json`` without
it); later runs on the same adapter read the choice instead of measuring, as long as it was made among
the same candidates (a new candidate is measured against the old ones, not passed over). A candidate
the device refuses (a shader its compiler rejects, a limit it exceeds) is left out and remembered as
failed, with the first line of why. A cache file that cannot be
read or parsed is ignored and rewritten; it is written atomically (``wgpu_rt.io.atomic_output``), so a
crash never leaves a half file, and an entry another process added meanwhile is kept.
"""

from __future__ import annotations

import json
import os
import warnings
from collections.abc import Callable
from pathlib import Path

import wgpu

from .errors import DeviceLimitError
from .io import atomic_output

CACHE_VERSION = 1
CACHE_DIR_ENV = "WGPU_RT_CACHE_DIR"


def cache_path() -> Path:
    own = os.environ.get(CACHE_DIR_ENV) or ""
    if own:
        return Path(own) / "autotune.json"
    base = os.environ.get("XDG_CACHE_HOME") or ""
    return (Path(base) if os.path.isabs(base) else Path.home() / ".cache") / "wgpu-rt" / "autotune.json"


class MeasuredChoices:
    """The cache and the measurements. ``timer`` turns what a candidate returns into seconds (None:
    nothing can be measured, so ``choose`` takes its default). ``measured`` counts the timer's calls in
    this process."""

    def __init__(self, ctx, path: str | os.PathLike | None = None, timer: Callable[[object], float] | None = None):
        self.ctx = ctx
        self.path = Path(path) if path is not None else cache_path()
        self.timer = timer
        info = ctx.adapter.info
        self.adapter = " | ".join(str(info.get(k, "")) for k in ("device", "description", "backend_type"))
        self.entries = self._load()
        self.measured = 0

    def _load(self) -> dict:
        """The cache's entries; {} when the file is missing, unreadable or not a cache of this version
        (it is rewritten on the next measurement)."""
        try:
            data = json.loads(self.path.read_text())
            entries = data["entries"] if data.get("version") == CACHE_VERSION else {}
            return {key: value for key, value in entries.items()
                    if isinstance(value, dict) and isinstance(value.get("variant"), str)}
        except (OSError, ValueError, AttributeError, KeyError, TypeError):
            return {}

    def cached(self, key: str, candidates=None) -> str | None:
        """The variant remembered for ``key``, if any (with ``candidates``: only if it was chosen among
        them all)."""
        entry = self.entries.get(key, {})
        timed, failed = entry.get("seconds"), entry.get("failed", {})
        if candidates is not None and not (isinstance(timed, dict) and isinstance(failed, dict)
                                           and set(candidates) <= set(timed) | set(failed)):
            return None
        return entry.get("variant")

    def choose(self, key: str, candidates: dict[str, Callable[[], object]], default: str) -> str:
        """The fastest of ``candidates`` (variant -> a callable giving what ``timer`` measures) for
        ``key``, from the cache or measured now; ``default`` where nothing can be measured or the device
        refused every candidate."""
        if len(candidates) == 1:
            return next(iter(candidates))
        cached = self.cached(key, candidates)
        if cached in candidates:
            return cached
        if self.timer is None:
            return default
        seconds, failed = {}, {}
        for variant, candidate in candidates.items():
            try:
                seconds[variant] = self.timer(candidate())
            except (wgpu.GPUError, DeviceLimitError) as err:
                failed[variant] = (str(err).strip().splitlines() or [type(err).__name__])[0]
            self.measured += 1
        if not seconds:
            return default
        best = min(seconds, key=seconds.get)
        self.entries[key] = {"variant": best, "seconds": seconds, **({"failed": failed} if failed else {})}
        self._save(key)
        return best

    def _save(self, key: str) -> None:
        """Add ``key`` to what is on disk now (another process may have added entries) and replace the
        file atomically."""
        entries = self._load()
        entries[key] = self.entries[key]
        self.entries.update(entries)
        try:
            with atomic_output(self.path) as tmp:
                tmp.write_text(json.dumps({"version": CACHE_VERSION, "entries": entries}, indent=1,
                                          sort_keys=True))
        except OSError as err:  # a cache that cannot be written costs a measurement next time, not the run
            warnings.warn(f"autotune cache not saved: {err}", stacklevel=2)
