"""Reading a rendered dataset back (training, validation, benchmarks).

``load_views(DIR, split)`` returns every finished view of that split with all its images in memory.
Anything wrong with the data is a ``DatasetError`` that names the file: a missing manifest, a missing
or unreadable EXR, a missing layer, or an image whose size differs from the view's.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ImageError
from .truth import GBUFFERS, DatasetError, frame_file


@dataclass
class Frame:
    """One frame of a view: noisy renders by spp and the gold render, each {"color", *GBUFFERS}; ``copies``
    holds the extra independent renders at the lowest spp (the dataset's ``noisy_copies`` − 1)."""

    noisy: dict[int, dict[str, np.ndarray]]
    gold: dict[str, np.ndarray]
    copies: list[dict[str, np.ndarray]] = field(default_factory=list)

    def renders_at(self, spp: int) -> list[dict[str, np.ndarray]]:
        """Every independent noisy render of this frame at ``spp``."""
        return [self.noisy[spp], *(self.copies if spp == min(self.noisy) else [])]


@dataclass
class View:
    view_id: str
    scene: str
    split: str
    frames: list[Frame]
    objects: list[str]

    @property
    def spp(self) -> list[int]:
        return sorted(self.frames[0].noisy)


def read_manifest(root: str | Path) -> dict:
    path = Path(root) / "manifest.json"
    if not path.is_file():
        raise DatasetError(f"{path}: no manifest; render the dataset first (wgpu-rt dataset --out {root})")
    try:
        manifest = json.loads(path.read_text())
    except json.JSONDecodeError as err:
        raise DatasetError(f"{path}: not valid JSON ({err})") from None
    if not isinstance(manifest, dict) or not isinstance(manifest.get("views"), list):
        raise DatasetError(f"{path}: has no 'views' list")
    if not isinstance(manifest.get("config", {}), dict):
        raise DatasetError(f"{path}: 'config' must be an object")
    for index, record in enumerate(manifest["views"]):
        _check_record(path, index, record)
    return manifest


# The fields of a view record the reader uses, with their types (ints at least 1).
RECORD_FIELDS = {"view_id": str, "scene": str, "split": str, "size": int, "frames": int, "spp": list}


def _check_record(path: Path, index: int, record) -> None:
    """A DatasetError naming the manifest, the view and the field for a record the reader cannot use."""
    if not isinstance(record, dict):
        raise DatasetError(f"{path}: views[{index}] is not an object")
    where = f"{path}: views[{index}] ({record.get('view_id', '?')})"
    for name, kind in RECORD_FIELDS.items():
        value = record.get(name)
        if not isinstance(value, kind) or isinstance(value, bool):
            raise DatasetError(f"{where}: '{name}' must be a {kind.__name__}, got {value!r}")
    counts = [record["size"], record["frames"], *record["spp"], record.get("noisy_copies", 1)]
    if not record["spp"] or not all(isinstance(v, int) and not isinstance(v, bool) and v >= 1 for v in counts):
        raise DatasetError(f"{where}: size, frames, spp and noisy_copies must be integers ≥ 1")
    if not isinstance(record.get("seconds", 0.0), (int, float)):
        raise DatasetError(f"{where}: 'seconds' must be a number, got {record['seconds']!r}")
    if record["split"] not in ("train", "val", "test"):
        raise DatasetError(f"{where}: split {record['split']!r} is not train, val or test")


def read_render(path: Path, size: tuple[int, int] | None) -> dict[str, np.ndarray]:
    """One EXR of the dataset as {"color", *GBUFFERS}, checked for layers, size and finiteness."""
    from ..io import read_exr, require_layers

    try:
        images = read_exr(path)
        require_layers(images, path, "color", *GBUFFERS)
    except ImageError as err:
        raise DatasetError(str(err)) from None
    for name in ("color", *GBUFFERS):
        image = images[name]
        if size is not None and image.shape[:2] != size:
            raise DatasetError(f"{path}: layer {name!r} is {image.shape[1]}×{image.shape[0]}, "
                               f"but this view's images are {size[1]}×{size[0]}")
        if not np.all(np.isfinite(image)):
            raise DatasetError(f"{path}: layer {name!r} holds NaN/Inf values")
    return {name: images[name] for name in ("color", *GBUFFERS)}


def load_view(root: Path, record: dict) -> View:
    folder = root / "views" / record["view_id"]
    size = (int(record["size"]), int(record["size"]))
    lowest = min(int(s) for s in record["spp"])
    frames = []
    for f in range(int(record["frames"])):
        noisy = {int(s): read_render(folder / frame_file(f, s), size) for s in record["spp"]}
        copies = [read_render(folder / frame_file(f, lowest, c), size)
                  for c in range(1, int(record.get("noisy_copies", 1)))]
        frames.append(Frame(noisy, read_render(folder / frame_file(f, "gold"), size), copies))
    return View(record["view_id"], record["scene"], record["split"], frames, record.get("objects", []))


def load_views(root: str | Path, split: str | None = None, limit: int | None = None) -> list[View]:
    """The finished views of ``split`` (all splits if None), at most ``limit`` of them."""
    root = Path(root)
    records = [r for r in read_manifest(root)["views"] if split is None or r["split"] == split]
    if limit is not None:
        records = records[:limit]
    return [load_view(root, r) for r in records]
