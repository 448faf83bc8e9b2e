"""A model whose weights lie between a network and its fine-tune: ``(1 − weight) · base + weight · tuned``.

A fine-tune that starts from a model stays close to it in weight space, and the straight line between the
two is nearly always a line of good models: points along it can keep most of what the fine-tune gained on
new data while giving back less of what the base did well (weight-space ensembling, e.g. WiSE-FT). The
shipped denoiser is such a point (BENCHMARKS.md §31). Only the two files are read (onnx and numpy, no
torch); the result has the base's graph, and a card that says how it was made, followed by both cards.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from ..errors import ModelError, OutputError
from ..io import atomic_output
from ..nn.graph import read_onnx
from .cards import embedded_card


def _input_exposure(model) -> str:
    """"on" where the ONNX model says it was trained with the exposure step (frame/denoise_chain.py's
    INPUT_EXPOSURE), else "off"."""
    from ..frame.denoise_chain import INPUT_EXPOSURE

    said = {prop.key: prop.value for prop in model.metadata_props}.get(INPUT_EXPOSURE)
    return "on" if said == "on" else "off"


def _structure(model) -> list[tuple[str, tuple[str, ...], tuple[str, ...]]]:
    return [(node.op_type, tuple(node.input), tuple(node.output)) for node in model.graph.node]


def blended_weights(base: dict[str, np.ndarray], tuned: dict[str, np.ndarray], weight: float,
                    name: str = "tuned") -> dict[str, np.ndarray]:
    """Each floating-point tensor of ``base`` moved ``weight`` of the way to ``tuned``'s; other tensors
    (shapes, indices) must be equal. ``name`` names the tuned model in errors."""
    if set(base) != set(tuned):
        missing = sorted(set(base) ^ set(tuned))[0]
        raise ModelError(f"{name}: not a fine-tune of the base (initializer {missing!r} is in one model only)")
    blended = {}
    for key, start in base.items():
        end = tuned[key]
        if start.shape != end.shape or start.dtype != end.dtype:
            raise ModelError(f"{name}: initializer {key!r} is {end.dtype}{list(end.shape)}, "
                             f"the base's {start.dtype}{list(start.shape)}")
        if np.issubdtype(start.dtype, np.floating):
            mixed = (1.0 - weight) * start.astype(np.float64) + weight * end.astype(np.float64)
            blended[key] = mixed.astype(start.dtype)
        elif np.array_equal(start, end):
            blended[key] = start
        else:
            raise ModelError(f"{name}: initializer {key!r} ({start.dtype}) differs from the base's and cannot be "
                             "interpolated")
    return blended


def blend_models(base_path: str | Path, tuned_path: str | Path, weight: float, out: str | Path) -> Path:
    """Write the blend of the ONNX files ``base_path`` and ``tuned_path`` (the same graph, ``tuned`` a
    fine-tune of ``base``) at ``weight`` (0: the base, 1: the fine-tune) to ``out``, with its card
    ``out.with_suffix('.md')``; both are written whole or not at all. Returns ``out``."""
    from onnx import numpy_helper

    base_path, tuned_path, out = Path(base_path), Path(tuned_path), Path(out)
    if not 0.0 <= weight <= 1.0:
        raise ModelError(f"--weight must be in [0, 1], got {weight}")
    if out.suffix != ".onnx":
        raise OutputError(f"--out {out}: name an .onnx file")
    if out.resolve() in (base_path.resolve(), tuned_path.resolve()):
        raise OutputError(f"--out {out}: would overwrite one of the models it reads; name another file")
    base, tuned = read_onnx(base_path), read_onnx(tuned_path)
    if _structure(base) != _structure(tuned):
        raise ModelError(f"{tuned_path}: its graph is not the base's ({base_path}); only a fine-tune of the same "
                         "architecture can be blended")
    if _input_exposure(base) != _input_exposure(tuned):
        raise ModelError(f"{tuned_path}: trained with the exposure step {_input_exposure(tuned)}, the base "
                         f"({base_path}) {_input_exposure(base)}: their weights read different inputs, so no "
                         "blend of them reads either")
    if _input_exposure(tuned) == "on":   # the blend reads its input as both were trained, and says so
        del base.metadata_props[:]
        base.metadata_props.extend(tuned.metadata_props)
    blended = blended_weights({i.name: numpy_helper.to_array(i) for i in base.graph.initializer},
                              {i.name: numpy_helper.to_array(i) for i in tuned.graph.initializer},
                              weight, str(tuned_path))
    for initializer in base.graph.initializer:
        initializer.CopyFrom(numpy_helper.from_array(blended[initializer.name], initializer.name))
    card = _card(base_path, tuned_path, weight, out)
    with atomic_output(out) as tmp_onnx, atomic_output(out.with_suffix(".md")) as tmp_card:
        tmp_onnx.write_bytes(base.SerializeToString())
        tmp_card.write_text(card, encoding="utf-8")
    return out


def _card(base_path: Path, tuned_path: Path, weight: float, out: Path) -> str:
    def digest(path: Path) -> str:
        return hashlib.sha256(path.read_bytes()).hexdigest()[:12]

    def card_of(path: Path) -> str:
        card = path.with_suffix(".md")
        return card.read_text(encoding="utf-8") if card.is_file() else "(no card beside it)"

    base_digest, tuned_card = digest(base_path), card_of(tuned_path)
    # a card written by `wgpu-rt train --init-from` names its base by hash and holds the base's card
    base_inside = f"sha256 {base_digest}" in tuned_card
    lines = [f"# {out.name} — blend of a model and its fine-tune", "",
             f"Written by `wgpu-rt blend {base_path} {tuned_path} --weight {weight:g} --out {out}`: every weight is "
             f"(1 − {weight:g}) × the base's + {weight:g} × the fine-tune's.", "",
             f"- base: `{base_path}` (sha256 {base_digest}…"
             + ("; its card is the fine-tune's 'Base model' below)" if base_inside else ")"),
             f"- fine-tune: `{tuned_path}` (sha256 {digest(tuned_path)}…)",
             "- the fine-tune's validation figures below are its own, not the blend's"]
    sections = [("Fine-tune", tuned_path, tuned_card)]
    if not base_inside:
        sections.append(("Base", base_path, card_of(base_path)))
    for title, path, text in sections:   # the fine-tune's own history stays; cards inside it lost theirs
        lines += embedded_card(title, path.with_suffix(".md").name, text, keep_history=title == "Fine-tune")
    return "\n".join(lines) + "\n"
