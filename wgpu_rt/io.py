"""Image files: multi-layer OpenEXR for HDR data, PNG for display previews.

EXR channel names (what our renderer writes and our denoiser reads):

| layer  | channels                        | meaning                                          |
| ------ | ------------------------------- | ------------------------------------------------ |
| color  | ``R``, ``G``, ``B``             | HDR radiance, linear Rec.709                     |
| albedo | ``albedo.R/G/B``                | first non-delta surface's reflectance            |
| normal | ``normal.X/Y/Z``                | world-space unit normal                          |
| depth  | ``depth.Z``                     | linear depth along the camera axis (0 = miss)    |
| motion | ``motion.X/Y``                  | pixels to the previous frame's position          |
| spp    | ``spp.Y``                       | samples taken in the pixel                       |

Any other layer ``name`` with C channels is written as ``name.0`` … ``name.{C-1}``. Writes are atomic
(a temporary file renamed into place), so an interrupted run never leaves a half-written image.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .errors import ImageError

LAYER_CHANNELS = {"color": "RGB", "albedo": "RGB", "normal": "XYZ", "depth": "Z", "motion": "XY",
                  "spp": "Y"}


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


def _atomic_target(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    return path.with_name(f".{path.name}.{os.getpid()}.tmp")


def write_exr(path: str | os.PathLike, color: np.ndarray, layers: dict | None = None,
              half: bool = False) -> None:
    """Write ``color`` (H, W, 3) and named ``layers`` ((H, W) or (H, W, C)) as one scanline EXR."""
    import OpenEXR

    path = Path(path)
    color = _as_hwc("color", color, None)
    channels = {}
    for name, array in {"color": color, **(layers or {})}.items():
        array = _as_hwc(name, array, color.shape[:2])
        for i, channel in enumerate(_channel_names(name, array.shape[2])):
            plane = np.ascontiguousarray(array[..., i])
            channels[channel] = plane.astype(np.float16) if half and name != "spp" else plane
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    tmp = _atomic_target(path)
    try:
        with OpenEXR.File(header, channels) as exr:
            exr.write(str(tmp))
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def read_exr(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read an EXR into {"color": (H, W, 3), layer: (H, W, C), …} float32 arrays.

    Channels are grouped by the text before their last dot; R/G/B (or X/Y/Z) order is restored.
    """
    import OpenEXR

    path = Path(path)
    if not path.is_file():
        raise ImageError(f"{path}: no such file")
    try:
        with OpenEXR.File(str(path), separate_channels=True) as exr:
            planes = {name: np.asarray(ch.pixels, dtype=np.float32) for name, ch in exr.channels().items()}
    except Exception as err:  # OpenEXR raises bare exceptions on corrupt files
        raise ImageError(f"{path}: not a readable OpenEXR file ({err})") from None
    groups: dict[str, dict[str, np.ndarray]] = {}
    for name, plane in planes.items():
        layer, _, suffix = name.rpartition(".")
        groups.setdefault(layer or "color", {})[suffix] = plane
    result = {}
    for layer, chans in groups.items():
        order = LAYER_CHANNELS.get(layer, "")
        if order and set(order) <= set(chans):
            keys = list(order)
        else:
            keys = sorted(chans, key=lambda s: (not s.isdigit(), int(s) if s.isdigit() else 0, s))
        result[layer] = np.stack([chans[k] for k in keys], axis=-1)
    return result


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
    tmp = _atomic_target(path)
    try:
        Image.fromarray(pixels).save(tmp, format="PNG")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
