"""``--shaping POTENTIAL``: potential-based reward shaping of the training batch
(:class:`trailer_env.sb3.PotentialShapingVecEnv`); the hyperparameter file's entry may give
it too (its ``shaping`` key)."""

from __future__ import annotations

import argparse
import ast
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

from agents.algorithms.options.base import (
    Flag,
    OptionError,
    RunFacts,
    TrainingOption,
    recorded_part,
)

if TYPE_CHECKING:
    from stable_baselines3.common.vec_env import VecEnv

#: The shaping's settings, in the order they are recorded.
FIELDS = ("potential", "scale", "reference")
#: The flag refusals name.
FLAG = "--shaping"


@dataclass(frozen=True)
class Shaping(TrainingOption):
    """Potential-based reward shaping: the training batch's rewards get
    ``gamma Phi(s') - Phi(s)`` (under the normalisation; sb3, one count of trailers: the
    potential is one n's LQR); the success metric and the recorded returns stay the
    scene's.

    Attributes:
        potential: A name of :data:`trailer_env.shaping.POTENTIALS` (``"lqr"``).
        scale, reference: The wrapper's keywords of those names (None: its defaults).
    """

    KEYS: ClassVar[tuple[str, ...]] = ("shaping",)
    FLAGS: ClassVar[tuple[Flag, ...]] = (
        Flag(
            FLAG,
            "text",
            "POTENTIAL",
            "potential-based reward shaping over the file's `shaping` (sb3 only): "
            "'lqr' (the log of the LQR's cost-to-go, trailer_env.shaping) or 'none'; the "
            "success metric and the recorded returns stay the scene's",
        ),
    )

    potential: str
    scale: float | None = None
    reference: float | None = None

    def __post_init__(self) -> None:
        from trailer_env.shaping import POTENTIALS

        if self.potential not in POTENTIALS:
            raise OptionError(
                FLAG,
                f"shaping needs a potential among {sorted(POTENTIALS)}, got {self.potential!r:.60}",
            )
        for name in FIELDS[1:]:
            number = getattr(self, name)
            if number is not None and not _finite(number):
                raise OptionError(
                    FLAG, f"shaping {name} must be a finite number, got {number!r:.60}"
                )

    @classmethod
    def given(cls, args: argparse.Namespace) -> bool:
        # ``--shaping none`` turns the file's shaping off: a run without the option.
        return args.shaping not in (None, "none")

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> Shaping | None:
        return cls.from_setting(args.shaping)

    @classmethod
    def from_setting(cls, value: object) -> Shaping | None:
        """The shaping a hyperparameter entry's ``shaping`` (or ``--shaping``) sets: None,
        False and ``"none"`` mean none; a potential's name, that potential with the
        wrapper's defaults; a ``dict(potential=..., scale=..., reference=...)`` string or
        a mapping, those keywords.

        Raises:
            OptionError: An unknown potential or keyword, or a value that is not a number.
        """
        if value is None or value is False or value == "none":
            return None
        if isinstance(value, str) and not value.lstrip().startswith("dict("):
            return cls(value.strip())
        if isinstance(value, str):
            value = _keywords(value)
        if not isinstance(value, Mapping):
            raise OptionError(FLAG, f"shaping must be a potential or a dict, got {value!r:.60}")
        for key in value:
            if key not in FIELDS:
                raise OptionError(FLAG, f"shaping has no {key!r} ({', '.join(FIELDS)})")
        potential = value.get("potential")
        return cls(
            potential if isinstance(potential, str) else repr(potential),
            value.get("scale"),
            value.get("reference"),
        )

    @classmethod
    def from_record(cls, record: Mapping[str, object]) -> Shaping | None:
        value = recorded_part(record, "shaping", FIELDS)
        if value is None:
            return None
        potential = value.get("potential")
        if not isinstance(potential, str):
            raise ValueError(f"shaping.potential must be a string, got {potential!r:.40}")
        for name in FIELDS[1:]:
            number = value.get(name)
            if number is not None and not _finite(number):
                raise ValueError(f"shaping.{name} must be a number, got {number!r:.40}")
        return cls.from_setting(value)

    def check(self, run: RunFacts) -> None:
        super().check(run)
        if isinstance(run.n_trailers, tuple):
            # The potential is one LQR's cost-to-go, designed for one n.
            raise OptionError(
                FLAG, "shaping (--shaping or the file's) needs one count of trailers, not a range"
            )

    def keywords(self) -> dict[str, object]:
        """The shaping wrapper's keywords (``gamma`` aside: the algorithm's)."""
        values = (self.potential, self.scale, self.reference)
        return {
            name: value for name, value in zip(FIELDS, values, strict=True) if value is not None
        }

    def record(self) -> dict[str, object]:
        return {"shaping": self.keywords()}

    def tag(self) -> str:
        return f" + {self.potential} shaping"

    def flags_text(self) -> str:
        if self.scale is None and self.reference is None:
            return f"{FLAG} {self.potential}"
        settings = ", ".join(f"{name}={value!r}" for name, value in self.keywords().items())
        return f'{FLAG} "dict({settings})"'

    def wrap(self, venv: VecEnv, *, gamma: float) -> VecEnv:
        from trailer_env.sb3 import PotentialShapingVecEnv

        return PotentialShapingVecEnv(venv, gamma=gamma, **self.keywords())  # type: ignore[arg-type]


def _finite(value: object) -> bool:
    """Whether ``value`` is a finite number (not a bool)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _keywords(text: str) -> Mapping[str, object]:
    """The keywords of a ``dict(name=literal, ...)`` string.

    Raises:
        OptionError: If it is not one, naming the flag.
    """
    try:
        node = ast.parse(text.strip(), mode="eval").body
        if (
            not isinstance(node, ast.Call)
            or not isinstance(node.func, ast.Name)
            or node.func.id != "dict"
            or node.args
            or any(keyword.arg is None for keyword in node.keywords)
        ):
            raise ValueError("not dict(name=value, ...)")
        return {str(item.arg): ast.literal_eval(item.value) for item in node.keywords}
    except (SyntaxError, ValueError) as error:
        raise OptionError(FLAG, f"shaping must be dict(name=value, ...): {error}") from None
