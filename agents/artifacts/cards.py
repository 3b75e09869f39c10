"""Model cards (JSON beside a model) and the JSON writer every record uses."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from agents.artifacts.paths import card_path


def read_card(model_path: Path) -> dict[str, Any]:
    """The model card of ``model_path``, or an empty dict when there is none.

    Raises:
        ValueError: If the card is not a JSON object.
    """
    path = card_path(model_path)
    if not path.is_file():
        return {}
    try:
        card = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ValueError(f"model card {path} is not JSON: {error}") from None
    if not isinstance(card, dict):
        raise ValueError(f"model card {path} is not a JSON object")
    return card


def write_json(path: Path, document: dict[str, Any]) -> Path:
    """Write a card or a run's ``config.json`` (sorted keys, so that files diff cleanly)."""
    path.write_text(json.dumps(document, indent=2, sort_keys=True) + "\n")
    return path


def write_card(model_path: Path, card: dict[str, Any]) -> Path:
    """Write the model card (JSON beside the model) that :func:`read_card` reads."""
    return write_json(card_path(model_path), card)
