"""Image files: multi-layer OpenEXR for HDR data, PNG for display previews.

EXR channel names (what our renderer writes and our denoiser reads):

| layer  | channels                        | meaning                                          |
| ------ | ------------------------------- | ------------------------------------------------ |
| color  | ``R``, ``G``, ``B``             | HDR radiance, linear Rec.709                     |
| albedo | ``albedo.R/G/B``                | first non-delta surface's reflectance (an        |
|        |                                 | emitter's at least 0.5); where the ray escapes,  |
|        |                                 | the background's radiance (≤ 1)                  |
| normal | ``normal.X/Y/Z``                | world-space unit normal                          |
| depth  | ``depth.Z``                     | linear depth along the camera axis (0 = miss)    |
| motion | ``motion.X/Y``                  | pixels to the previous frame's position          |
| spp    | ``spp.Y``                       | samples taken in the pixel                       |
| half_radiance | ``half_radiance.R/G/B``  | the mean after the first half of the samples     |
| half_spp | ``half_spp.Y``                | the samples in that mean                         |

Any other layer ``name`` with C channels is written as ``name.0`` … ``name.{C-1}``. Read back, a layer's
channels keep their file order where their names are a known set (R/G/B/A, X/Y/Z/W, U/V/W; numbers in
numeric order), and ``read_exr``'s result carries each layer's channel names (``ExrLayers.channels``), which
``write_exr`` takes back, so a file another renderer wrote keeps its layers' names when rewritten. A multi-part
file (Blender 5 writes its multilayer EXR as one part per pass) is read whole, and written back as one part.

Every file wgpu-rt writes goes through ``atomic_output`` (a temporary file renamed into place), so an
interrupted run never leaves a half-written file, and every output path a user names is checked by
``check_output_path`` before any work starts.
"""

from __future__ import annotations

import contextlib
import functools
import io
import json
import os
import sys
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from .errors import ImageError, OutputError

LAYER_CHANNELS = {"color": "RGB", "albedo": "RGB", "normal": "XYZ", "depth": "Z", "motion": "XY",
                  "spp": "Y", "half_radiance": "RGB", "half_spp": "Y"}
AUX_SAMPLES_ATTRIBUTE = "wgpuRtAuxSamples"   # the aux pass's samples behind the albedo layer; 0: the colour's
PART_ATTRIBUTES = {"name", "chunkCount", "version", "view"}   # a multi-part file's per-part layout
CHANNEL_SETS = ("RGBA", "XYZW", "UVW")   # channel names whose order is known, whatever the file's order


class ExrLayers(dict):
    """``read_exr``'s {layer: (H, W, C) array}, with ``channels``: each layer's channel names (``R``, ``X``,
    ``0`` …, without the layer's prefix) in the order of the array's last axis, and ``attributes``: the
    header's text and integer attributes (``generatedBy``, ours: AUX_SAMPLES_ATTRIBUTE)."""

    def __init__(self, arrays: dict, channels: dict, attributes: dict | None = None):
        super().__init__(arrays)
        self.channels = channels
        self.attributes = attributes or {}


def _channel_order(suffixes) -> list[str]:
    """Channel names in their known order: R, G, B, A (or X, Y, Z, W; U, V, W), else numbers in numeric
    order before other names in alphabetical order."""
    for known in CHANNEL_SETS:
        if set(suffixes) <= set(known):
            return sorted(suffixes, key=known.index)
    return sorted(suffixes, key=lambda s: (not s.isdigit(), int(s) if s.isdigit() else 0, s))


def _channel_names(layer: str, count: int) -> list[str]:
    letters = LAYER_CHANNELS.get(layer)
    suffixes = list(letters) if letters and len(letters) == count else [str(i) for i in range(count)]
    return suffixes if layer == "color" else [f"{layer}.{s}" for s in suffixes]


def _as_hwc(name: str, array: np.ndarray, shape: tuple[int, int] | None) -> np.ndarray:
    array = np.asarray(array, dtype=np.float32)
    if array.ndim == 2:
        array = array[..., None]
    if array.ndim != 3:
        raise ValueError(f"layer {name!r} must be (H, W) or (H, W, C), got shape {array.shape}")
    if shape is not None and array.shape[:2] != shape:
        raise ValueError(f"layer {name!r} is {array.shape[:2]}, but color is {shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"layer {name!r} holds {np.count_nonzero(~np.isfinite(array))} NaN/Inf values")
    return array


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` (its folders created) to write to; on success it replaces
    ``path``, on any failure (KeyboardInterrupt included) it is removed and ``path`` is left as it was.

    The temporary name ends in ``.tmp`` so that no glob for the real suffix picks up one left by a
    SIGKILL. An OSError about the temporary file, or about no file (a full disk), is re-raised naming
    ``path``, the name the user knows, so that the CLI can report it in one line."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        yield tmp
        os.replace(tmp, path)
    except OSError as err:
        if err.filename is None or os.fsdecode(err.filename) == str(tmp):
            raise OSError(err.errno, err.strerror or str(err), str(path)) from err
        raise
    finally:
        if tmp.exists():   # not unlink(missing_ok=True): a read-only file system refuses even that
            tmp.unlink()


def check_output_path(path: str | os.PathLike, flag: str, suffixes: tuple[str, ...] | None = None) -> Path:
    """``path`` if a file can be written there, else an OutputError naming ``flag`` and ``path``: called
    before any work, so that a bad output path costs a second, not a finished render. Refused: a
    suffix not in ``suffixes`` (compared lower-case), an existing folder, a file where a folder must
    be, and a folder nothing can be created in (tried for real: root ignores permission bits but not
    a read-only mount, and ``os.access`` cannot see every such case)."""
    path = Path(path)
    if suffixes is not None and path.suffix.lower() not in suffixes:
        raise OutputError(f"{flag} {path}: the output must end in {' or '.join(suffixes)}")
    if path.is_dir():
        raise OutputError(f"{flag} {path}: is a folder; name a file")
    folder = path.parent
    while not folder.exists():   # the folders atomic_output will create; the first existing one decides
        folder = folder.parent
    if not folder.is_dir():
        raise OutputError(f"{flag} {path}: {folder} is a file, not a folder")
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as err:
        raise OutputError(f"{flag} {path}: cannot write in {folder} ({err.strerror})") from None
    return path


def write_exr(path: str | os.PathLike, color: np.ndarray, layers: dict | None = None,
              half: bool = False, channel_names: dict | None = None, attributes: dict | None = None) -> None:
    """Write ``color`` (H, W, 3) and named ``layers`` ((H, W) or (H, W, C)) as one scanline EXR.
    ``channel_names``: {layer: its channels' names} for layers whose names are not this module's (as
    ``read_exr`` gives them in ``ExrLayers.channels``); ``attributes``: header attributes (text or int)."""
    import OpenEXR

    path = Path(path)
    color = _as_hwc("color", color, None)
    channels = {}
    for name, array in {"color": color, **(layers or {})}.items():
        array = _as_hwc(name, array, color.shape[:2])
        given = (channel_names or {}).get(name)
        names = (_channel_names(name, array.shape[2]) if given is None or len(given) != array.shape[2]
                 else [s if name == "color" else f"{name}.{s}" for s in given])
        for i, channel in enumerate(names):
            plane = np.ascontiguousarray(array[..., i])
            channels[channel] = plane.astype(np.float16) if half and name != "spp" else plane
    header = {**(attributes or {}), "compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with atomic_output(path) as tmp, OpenEXR.File(header, channels) as exr:
        try:
            exr.write(str(tmp))
        except RuntimeError as err:   # how OpenEXR reports a failed write (no permission, a full disk)
            raise OutputError(f"{path}: cannot write ({str(err).replace(str(tmp), str(path))})") from None


def read_exr(path: str | os.PathLike) -> ExrLayers:
    """Read an EXR into {"color": (H, W, C), layer: (H, W, C), …} float32 arrays.

    Channels are grouped by the text before their last dot ("color": those without one); each group's
    channels in their known order (``_channel_order``), their names in the result's ``channels``. Every
    part of a multi-part file is read (their channel names must differ and their sizes agree); the
    ``attributes`` are the first part's text and integer ones, less those that describe a part
    (PART_ATTRIBUTES), so they can be written into another file as they are.
    """
    import OpenEXR

    path = Path(path)
    if not path.is_file():
        raise ImageError(f"{path}: no such file")
    printed: list[str] = []
    planes: dict[str, np.ndarray] = {}
    try:
        with _library_output_captured(printed), OpenEXR.File(str(path), separate_channels=True) as exr:
            for part in exr.parts:   # a multi-part file (Blender's multilayer EXR: a part per pass) as one
                for name, channel in part.channels.items():
                    if name in planes:
                        raise ImageError(f"{path}: channel {name!r} appears in more than one part")
                    planes[name] = np.asarray(channel.pixels, dtype=np.float32)
                    if planes[name].shape[:2] != next(iter(planes.values())).shape[:2]:
                        raise ImageError(f"{path}: part {part.name()!r} is {part.width()}×{part.height()} "
                                         "pixels, unlike the file's first part")
            attributes = {key: value for key, value in exr.header().items()
                          if isinstance(value, (str, int)) and not isinstance(value, bool)
                          and key not in PART_ATTRIBUTES}
    except ImageError:
        raise
    except Exception as err:  # OpenEXR raises bare exceptions on corrupt files
        # Its own first diagnostic names the damage ("Invalid chunk size …"); on a truncated file the
        # exception only says "file has 0 parts".
        reason = printed[0].removeprefix(f"{path}: ") if printed else str(err)
        raise ImageError(f"{path}: not a readable OpenEXR file ({reason})") from None
    groups: dict[str, dict[str, np.ndarray]] = {}
    for name, plane in planes.items():
        layer, _, suffix = name.rpartition(".")
        groups.setdefault(layer or "color", {})[suffix] = plane
    names = {layer: _channel_order(chans) for layer, chans in groups.items()}
    return ExrLayers({layer: np.stack([groups[layer][k] for k in keys], axis=-1) for layer, keys in names.items()},
                     names, attributes)


def require_layers(images: dict, path, *names: str) -> None:
    """Raise ImageError naming ``path`` and the first layer of ``names`` that ``images`` lacks."""
    for name in names:
        if name not in images:
            expected = ", ".join(_channel_names(name, len(LAYER_CHANNELS.get(name, "RGB"))))
            present = ", ".join(sorted(images)) or "none"
            raise ImageError(f"{path}: missing layer {name!r} (channels {expected}); layers present: {present}")


def write_png(path: str | os.PathLike, display: np.ndarray) -> None:
    """Write display-referred values in [0, 1] ((H, W, 3) float, already tonemapped) as 8-bit PNG."""
    from PIL import Image

    path = Path(path)
    display = np.nan_to_num(np.asarray(display, dtype=np.float32), nan=0.0, posinf=1.0, neginf=0.0)
    pixels = (np.clip(display, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    with atomic_output(path) as tmp:
        Image.fromarray(pixels).save(tmp, format="PNG")


def write_json(path: str | os.PathLike, payload) -> None:
    """Write ``payload`` as indented JSON, atomically."""
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(payload, indent=1))


_CAPTURE_LOCK = threading.Lock()   # the descriptors are the process's: two threads must not swap them


@functools.cache
def _capture_file(pid: int):
    """One temporary file per process (a forked child gets its own) to catch C output in: making one
    per read would cost more than reading a small EXR."""
    return tempfile.TemporaryFile()


@contextlib.contextmanager
def _library_output_captured(lines: list[str]) -> Iterator[None]:
    """Catch what a library prints while it runs, and append those lines to ``lines`` on exit: OpenEXR
    prints its own lines about a corrupt file ahead of our one-line error, from C (to file descriptors
    1 and 2) and through Python's ``sys.stdout`` (which need not be descriptor 1, as under pytest)."""
    import ctypes

    sys.stdout.flush()
    sys.stderr.flush()
    python_output = io.StringIO()
    with _CAPTURE_LOCK:
        sink = _capture_file(os.getpid())
        sink.seek(0)
        sink.truncate()
        saved = {fd: os.dup(fd) for fd in (1, 2)}
        try:
            for fd in saved:
                os.dup2(sink.fileno(), fd)
            with contextlib.redirect_stdout(python_output), contextlib.redirect_stderr(python_output):
                yield
        finally:
            ctypes.CDLL(None).fflush(None)   # C++ iostreams sit in C stdio buffers: flush them into the sink
            for fd, copy in saved.items():
                os.dup2(copy, fd)
                os.close(copy)
            sink.seek(0)
            printed = sink.read().decode(errors="replace") + python_output.getvalue()
            lines.extend(line for line in printed.splitlines() if line.strip())
