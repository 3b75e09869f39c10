"""RLlib run files: the pickle-free policy export beside RLlib's checkpoint."""

from __future__ import annotations

from pathlib import Path

from agents.artifacts import files, limits
from agents.artifacts.cards import ModelCard

#: Files of the pickle-free policy export inside a checkpoint folder.
POLICY_WEIGHTS = "policy_weights.pt"


POLICY_CARD = "policy_card.json"


def is_rllib_checkpoint(path: Path) -> bool:
    """Whether ``path`` is a folder written by :func:`train_rllib` (or RLlib's ``save_to_path``)."""
    return path.is_dir() and (
        (path / POLICY_CARD).is_file() or (path / "rllib_checkpoint.json").is_file()
    )


def read_rllib_card(path: Path) -> ModelCard:
    """The policy card of an RLlib checkpoint folder (the empty card when it has none).

    Raises:
        ValueError: If it is too large, not a card, or asks for a network past the bound
            (:func:`agents.artifacts.limits.network_problem`).
    """
    card_file = path / POLICY_CARD
    if not card_file.is_file():
        return ModelCard()
    card = ModelCard.from_json(
        files.read_json(card_file, "policy card", allow_nan=True), str(card_file)
    )
    hiddens = card.rllib_hiddens
    if hiddens is not None:
        problem = limits.network_problem(hiddens)
        if problem is not None:
            raise ValueError(f"{card_file}: {problem}")
    return card
