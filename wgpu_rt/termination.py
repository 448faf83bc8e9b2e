"""SIGTERM ends a command as Ctrl-C does, even where a library swallows the exception it raises.

The CLI installs ``on_sigterm``, which raises ``SystemExit(143)`` wherever the program is, so cleanup runs
(no half-written output; ``wgpu-rt dataset`` lists the views it finished). A library that catches
``BaseException`` can swallow it (trimesh's vertex normals fall back to a loop on any exception), so the
signal is also remembered: long loops call ``raise_if_terminated()`` between their units of work, and the
CLI exits 143 when a terminated command returned anyway.
"""

from __future__ import annotations

import signal

_received: int | None = None


def on_sigterm(signum, frame):
    global _received
    _received = signum
    raise SystemExit(128 + signum)


def install():
    """Forget an earlier signal and handle SIGTERM from now on (main thread only); returns the old handler."""
    global _received
    _received = None
    return signal.signal(signal.SIGTERM, on_sigterm)


def uninstall(previous):
    """Put back the handler ``install`` replaced and forget the signal."""
    global _received
    _received = None
    signal.signal(signal.SIGTERM, previous)


def received() -> int | None:
    """The signal number this process was terminated with, or None."""
    return _received


def raise_if_terminated():
    """Exit now (status 128 + signal) if a SIGTERM arrived and something swallowed its exception."""
    if _received is not None:
        raise SystemExit(128 + _received)
