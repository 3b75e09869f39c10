"""Model cards (JSON beside a model): reading them checked, writing them atomically.

A card is a JSON object (:data:`~agents.artifacts.files.MAX_JSON_BYTES` at most). The
keys the agents read must have their types (:data:`CARD_TYPES`: ``algo`` a string,
``env_kwargs`` an object, ``timesteps`` an integer ...); any other key is kept as is.
A card that breaks this is refused with a :class:`ValueError` naming the key.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from agents.artifacts import files
from agents.artifacts.paths import card_path
from trailer_env.json_types import JSONObject

_INT = (int,)
_NUMBER = (int, float)
#: Keys of a card that the agents read, and the JSON types each may have (None: null).
CARD_TYPES: dict[str, tuple[type, ...]] = {
    "algo": (str,),
    "env_id": (str,),
    "recipe": (str,),
    "policy": (str,),
    "expert": (str,),
    "env_kwargs": (dict,),
    "hyperparams": (dict,),
    "validation": (dict,),
    "imitation": (dict,),
    "planner": (dict,),
    "normalize": (dict, type(None)),
    "command": (list,),
    "seed": (int, type(None)),
    "timesteps": _INT,
    "budget": _INT,
    "n_envs": _INT,
    "selected_at_timesteps": _INT,
    "selected_at_iteration": _INT,
    "simulated_steps": _INT,
    "wall_time_s": _NUMBER,
}


def is_count_range(value: object) -> bool:
    """Whether a card's ``n_trailers`` is a range ``[low, high]`` (a generalist's)."""
    return (
        isinstance(value, (list, tuple))
        and len(value) == 2
        and all(files.is_integer(bound, 0) for bound in value)
        and value[0] < value[1]
    )


def check_card(card: object, where: str) -> JSONObject:
    """``card`` if it is a card object whose known keys have their types.

    Raises:
        ValueError: Naming ``where`` and the first key that is wrong.
    """
    if not isinstance(card, dict):
        raise ValueError(f"model card {where} is not a JSON object")
    for key, types in CARD_TYPES.items():
        if key not in card:
            continue
        value = card[key]
        wrong = isinstance(value, bool) or not isinstance(value, types)
        if isinstance(value, float) and not files.is_number(value):
            wrong = True
        if wrong:
            names = " or ".join("null" if kind is type(None) else kind.__name__ for kind in types)
            raise ValueError(
                f"model card {where}: {key!r} must be {names}, got {type(value).__name__} "
                f"{value!r:.60}"
            )
    trailers = card.get("env_kwargs", {}).get("n_trailers")
    if trailers is not None and not (files.is_integer(trailers) or is_count_range(trailers)):
        raise ValueError(
            f"model card {where}: env_kwargs.n_trailers must be an integer or a pair "
            "[low, high] of integers with low < high (a generalist)"
        )
    return card


def trained_with_mirror(card: JSONObject) -> bool:
    """Whether the card's model was imitated with the mirror image (``imitate --mirror``):
    such a model acts as the mean of its network and the network's mirror image."""
    imitation = card.get("imitation")
    return isinstance(imitation, dict) and imitation.get("mirror") is True


def read_card(model_path: Path) -> JSONObject:
    """The model card of ``model_path``, or an empty dict when there is none.

    Raises:
        ValueError: If the card is too large or deep, not a JSON object, or a known key
            has the wrong type (:func:`check_card`).
    """
    path = card_path(model_path)
    if not path.is_file():
        return {}
    return check_card(files.read_json(path, "model card", allow_nan=True), str(path))


def write_card(model_path: Path, card: Mapping[str, object]) -> Path:
    """Write the model card (JSON beside the model) that :func:`read_card` reads."""
    return files.write_json(card_path(model_path), card)
