"""A run's recipe, named from its record: :func:`recipe_name` over the table :data:`RECIPE_TAGS`
and the training options' tags (:data:`agents.algorithms.options.TRAINING_OPTIONS`)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

from agents.algorithms import DEFAULT_NET_ARCH
from agents.algorithms.options import recorded_options

__all__ = ["RECIPE_TAGS", "RecipeTag", "recipe_name"]


def _at(record: Mapping[str, object], *path: str) -> object:
    """The value at ``path`` in a record's nested objects (None where it has none)."""
    value: object = record
    for key in path:
        value = value.get(key) if isinstance(value, Mapping) else None
    return value


def _gsde(record: Mapping[str, object]) -> str | None:
    """gSDE: PPO's argument, or SAC's and TD3's ``policy_kwargs`` entry."""
    paths = (("hyperparams", "use_sde"), ("hyperparams", "policy_kwargs", "use_sde"))
    return "gSDE" if any(_at(record, *path) is True for path in paths) else None


def _net_width(record: Mapping[str, object]) -> str | None:
    """The hidden layers as "256x256" when recorded and not :data:`DEFAULT_NET_ARCH`."""
    arch = _at(record, "hyperparams", "policy_kwargs", "net_arch")
    if not isinstance(arch, list) or arch == list(DEFAULT_NET_ARCH):
        return None
    return "x".join(str(width) for width in arch)


def _randomize(record: Mapping[str, object]) -> str | None:
    """Randomised physics: the preset's name ("mismatch20"), else "randomised"."""
    randomize = _at(record, "env_kwargs", "randomize")
    if randomize is None:
        return None
    return randomize if isinstance(randomize, str) else "randomised"


def _by_row(record: Mapping[str, object]) -> str | None:
    """Counts fixed by the batch row (``trailer_draw="row"``)."""
    return "n by row" if _at(record, "env_kwargs", "trailer_draw") == "row" else None


def _history(record: Mapping[str, object]) -> str | None:
    """A memory: the window of past frames the policy reads ("history 16")."""
    history = _at(record, "env_kwargs", "history")
    return f"history {history}" if isinstance(history, int) and history > 0 else None


@dataclass(frozen=True)
class RecipeTag:
    """One part of a recipe's name, read from the run's record: it goes in the parentheses
    after the algorithm ("ppo (gSDE)"); the training options' tags follow them
    ("ppo (gSDE) + lqr shaping").

    Attributes:
        name: What it marks.
        read: The part's text for a record, or None when the record has no such part.
    """

    name: str
    read: Callable[[Mapping[str, object]], str | None]


#: The parts of a recipe's name that are not training options, in their order.
RECIPE_TAGS: tuple[RecipeTag, ...] = (
    RecipeTag("state-dependent exploration", _gsde),
    RecipeTag("a network other than DEFAULT_NET_ARCH", _net_width),
    RecipeTag("randomised physics", _randomize),
    RecipeTag("counts fixed by the batch row", _by_row),
    RecipeTag("a memory of past frames", _history),
)


def recipe_name(record: Mapping[str, object], upper: bool = False) -> str:
    """A run's recipe from its configuration or model card: "ppo", "ppo (gSDE)",
    "ppo (gSDE, 256x256)", "ppo (gSDE) + lqr shaping", "ppo (gSDE) + start curriculum",
    "ppo (gSDE, 256x256) + start replay 0.25", "ppo (mismatch20)", "ppo (n by row)",
    "dagger (mismatch20, history 16)",
    "ppo from dagger_reverse_v1_n4" (the algorithm's name upper-cased when ``upper``).

    Each of :data:`RECIPE_TAGS` and each training option the record holds is a recipe of
    its own: runs are grouped, tabled and labelled by this name, so that they are never
    averaged with the plain algorithm's.

    Raises:
        ValueError: If a training option's part of the record is malformed.
    """
    name = str(_at(record, "algo") or "?")
    if upper:
        name = name.upper()
    inside = [text for tag in RECIPE_TAGS if (text := tag.read(record))]
    if inside:
        name += f" ({', '.join(inside)})"
    return name + "".join(option.tag() for option in recorded_options(record))
