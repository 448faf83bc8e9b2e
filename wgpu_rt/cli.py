"""The ``wgpu-rt`` command line.

Each subcommand is a module of ``wgpu_rt.commands`` with ``HELP`` (one line), ``add_arguments(parser)``
and ``run(args) -> int``; modules import their heavy dependencies inside ``run`` so that ``--help``
stays fast. Modules whose name starts with ``_`` are helpers the subcommands share. Errors a user can
cause (``WgpuRtError``, or an ``OSError`` about a named path) print one line and exit 2; a reader of
stdout that leaves early (``| head``) ends the command quietly with status 141; SIGTERM ends it as Ctrl-C
does, its cleanup run, with status 143 (``wgpu_rt.termination``).
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys
import threading

from . import __version__, commands, termination
from .errors import WgpuRtError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="wgpu-rt", description="Path trace on WebGPU and denoise with WGSL neural networks, on one device.")
    parser.add_argument("--version", action="version", version=f"wgpu-rt {__version__}")
    parser.add_argument("--adapter", help="use the adapter whose name contains this text "
                        "(default: $WGPU_RT_ADAPTER, else the best: a real GPU before lavapipe)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        name = info.name.replace("_", "-")
        command = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(command)
        command.set_defaults(run=module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.adapter:
        from .gpu import ADAPTER_ENV
        os.environ[ADAPTER_ENV] = args.adapter
    on_main_thread = threading.current_thread() is threading.main_thread()
    previous = termination.install() if on_main_thread else None
    try:
        status = int(args.run(args) or 0)
        sys.stdout.flush()   # inside the try: a reader gone shows here, not at the interpreter's exit
        signum = termination.received()   # a SIGTERM whose exit a library swallowed
        return 128 + signum if signum is not None else status
    except BrokenPipeError:
        # the reader of stdout left (`wgpu-rt info | head`): stop quietly, as other command-line tools do;
        # stdout goes to /dev/null so that the interpreter's own flush at exit does not fail again
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except WgpuRtError as err:
        print(f"wgpu-rt {args.command}: error: {err}", file=sys.stderr)
        return 2
    except OSError as err:
        # A path the user named that the system refused (permission, full disk, a folder in the way),
        # found only while writing; an OSError without a file name is a bug and keeps its traceback.
        if err.filename is None:
            raise
        print(f"wgpu-rt {args.command}: error: {err.filename}: {err.strerror}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"wgpu-rt {args.command}: interrupted", file=sys.stderr)
        return 130
    finally:
        if on_main_thread:
            termination.uninstall(previous)


if __name__ == "__main__":
    sys.exit(main())
