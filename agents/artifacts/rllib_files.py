"""RLlib run files: the pickle-free policy export beside RLlib's checkpoint."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

#: Files of the pickle-free policy export inside a checkpoint folder.
POLICY_WEIGHTS = "policy_weights.pt"


POLICY_CARD = "policy_card.json"


def is_rllib_checkpoint(path: Path) -> bool:
    """Whether ``path`` is a folder written by :func:`train_rllib` (or RLlib's ``save_to_path``)."""
    return path.is_dir() and (
        (path / POLICY_CARD).is_file() or (path / "rllib_checkpoint.json").is_file()
    )


def read_rllib_card(path: Path) -> dict[str, Any]:
    """The policy card of an RLlib checkpoint folder (empty when it has none)."""
    card = path / POLICY_CARD
    return dict(json.loads(card.read_text())) if card.is_file() else {}
