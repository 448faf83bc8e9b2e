"""Model-card text shared by the trainer and `wgpu-rt blend`: another model's card embedded in a new one."""

from __future__ import annotations


def without_history_tables(card: str) -> str:
    """``card`` (a model card's markdown) less the table rows of its history sections, embedded cards' included:
    an older card kept a row per epoch, thousands of them."""
    kept, in_history = [], False
    for line in card.splitlines():
        if line.startswith("#"):
            in_history = line.lstrip("#").strip() == "History"
        if not (in_history and line.startswith("|")):
            kept.append(line)
    return "\n".join(kept)


def embedded_card(title: str, card_name: str, card: str, keep_history: bool = False) -> list[str]:
    """The lines that embed ``card`` (the file ``card_name`` as it was) in a new card: a ``title`` heading,
    then the card with its headings one level down and, unless ``keep_history``, its history tables left out."""
    text = card if keep_history else without_history_tables(card)
    return ["", f"## {title} (`{card_name}` as it was, headings one level down"
            + ("" if keep_history else ", history tables left out") + ")", "",
            *("#" + line if line.startswith("#") else line for line in text.splitlines())]
