"""The record every training option is: flags, checks, its part of the run record, its
tag in the recipe's name and what it attaches to training."""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar, Literal, Protocol, TypeVar

if TYPE_CHECKING:
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecEnv

OptionT = TypeVar("OptionT", bound="TrainingOption")

#: The kinds of value a flag takes; the command line parses each (agents.commands.options):
#: a share in (0, 1), an integer in ``low .. high``, ``FROM,STEPS`` (a scale in (0, 1)
#: and a step count), a file, a text the option reads itself.
ValueKind = Literal["share", "count", "schedule", "path", "text"]


@dataclass(frozen=True)
class Flag:
    """One command-line flag of a training option.

    Attributes:
        name: The flag, e.g. ``--start-replay``; its value is ``args.start_replay``.
        kind: What its value is (:data:`ValueKind`).
        metavar: Its value's name in the help.
        help: The help text.
        low, high: A ``count``'s bounds.
        default: The value when the flag is not given.
    """

    name: str
    kind: ValueKind
    metavar: str
    help: str
    low: int = 0
    high: int = 2**31
    default: int | None = None

    @property
    def dest(self) -> str:
        """The attribute of the parsed arguments that holds its value."""
        return self.name.lstrip("-").replace("-", "_")


class OptionError(ValueError):
    """A training option's value that the run cannot use; ``flag`` is the option to name."""

    def __init__(self, flag: str, message: str) -> None:
        super().__init__(message)
        self.flag = flag


class RunFacts(Protocol):
    """What an option checks itself against: the run's settings
    (:class:`agents.training.config.TrainConfig`)."""

    @property
    def env_id(self) -> str: ...

    @property
    def algo(self) -> str: ...

    @property
    def backend(self) -> str: ...

    @property
    def budget(self) -> int: ...

    @property
    def n_trailers(self) -> int | tuple[int, int]: ...

    @property
    def env_kwargs(self) -> Mapping[str, object]: ...


class StartScalable(Protocol):
    """The training environment as options see it (:class:`trailer_env.sb3.ConvoySB3VecEnv`,
    possibly under wrappers: ``unwrapped`` is the batch itself)."""

    @property
    def unwrapped(self) -> object: ...


@dataclass(frozen=True)
class TrainingOption:
    """One training option (``--start-replay``, ``--init-from`` ...): a frozen record of
    its values.

    A subclass declares its command-line flags (:attr:`FLAGS`), reads them
    (:meth:`from_args`, refusing a bad value with :class:`OptionError`), checks itself
    against the command and the run (:meth:`check_command`, :meth:`check`), writes its
    part of the run record and reads it back (:meth:`record`, :meth:`from_record`), names
    itself in the recipe (:meth:`tag`) and in refusals (:meth:`flags_text`), and
    attaches itself to an SB3 run (:meth:`wrap` around the training batch,
    :meth:`prepare` before the first reset, :meth:`callbacks` during it). It is one entry of
    :data:`agents.algorithms.options.TRAINING_OPTIONS`.
    """

    #: Its keys in the run record (``config.json`` and every model card).
    KEYS: ClassVar[tuple[str, ...]] = ()
    #: Its command-line flags, the main one first.
    FLAGS: ClassVar[tuple[Flag, ...]] = ()
    #: The backends that have it.
    BACKENDS: ClassVar[tuple[str, ...]] = ("sb3",)

    @classmethod
    def flag(cls) -> str:
        """Its main flag (the one refusals name)."""
        return cls.FLAGS[0].name

    @classmethod
    def given(cls, args: argparse.Namespace) -> bool:
        """Whether the command line gives any of its flags (other than at its default)."""
        return any(getattr(args, flag.dest, None) != flag.default for flag in cls.FLAGS)

    @classmethod
    def from_args(cls: type[OptionT], args: argparse.Namespace) -> OptionT | None:
        """The option the command line gives, or None.

        Raises:
            OptionError: On values that do not go together, naming the flag.
        """
        raise NotImplementedError

    @classmethod
    def from_record(cls: type[OptionT], record: Mapping[str, object]) -> OptionT | None:
        """The option a run record holds (None: the run had none).

        Raises:
            ValueError: If its part is malformed, naming the key.
        """
        raise NotImplementedError

    def check_command(self, env_id: str, algo: str, backend: str) -> None:
        """Refuse a scene, algorithm or backend this option cannot be part of (checked
        before any file is read).

        Raises:
            OptionError: Naming the flag.
        """
        del env_id, algo
        if backend not in self.BACKENDS:
            raise OptionError(self.flag(), f"not supported with --backend {backend}")

    def check(self, run: RunFacts) -> None:
        """Refuse a run this option cannot be part of (:meth:`check_command` included).

        Raises:
            OptionError: Naming the flag.
        """
        self.check_command(run.env_id, run.algo, run.backend)

    def record(self) -> dict[str, object]:
        """Its part of the run record (JSON-ready), under :attr:`KEYS`."""
        raise NotImplementedError

    def tag(self) -> str:
        """Its part of the recipe's name, e.g. ``" + start replay 0.25"``."""
        raise NotImplementedError

    def flags_text(self) -> str:
        """The command-line flags that give it again (for refusal messages)."""
        raise NotImplementedError

    @classmethod
    def absent_text(cls) -> str:
        """:meth:`flags_text` of a run without it."""
        return f"no {cls.flag()}"

    def same_run(self, other: TrainingOption) -> bool:
        """Whether a run recorded with ``other`` may go on with this option."""
        return self == other

    def wrap(self, venv: VecEnv, *, gamma: float) -> VecEnv:
        """The training batch under its wrapper, inside the normalisation (``venv`` by
        default); ``gamma`` is the algorithm's discount."""
        del gamma
        return venv

    def prepare(self, venv: StartScalable, *, seed: int, start_steps: int) -> None:
        """Set the training environment up before its first reset (nothing by default)."""

    def callbacks(self) -> list[BaseCallback]:
        """The callbacks it adds to the training loop (none by default)."""
        return []


def recorded_part(
    record: Mapping[str, object], key: str, fields: tuple[str, ...]
) -> Mapping[str, object] | None:
    """``record[key]`` when it is an object of (some of) ``fields``, None when absent.

    Raises:
        ValueError: If it is not an object or has another field, naming the key.
    """
    value = record.get(key)
    if value is None:
        return None
    if not isinstance(value, Mapping):
        raise ValueError(f"{key} must be an object, got {value!r:.40}")
    for name in value:
        if name not in fields:
            raise ValueError(f"{key} has no field {name!r} ({', '.join(fields)})")
    return value


def recorded_number(value: object, key: str) -> float:
    """``value`` as a number of a run record.

    Raises:
        ValueError: If it is not a number, naming ``key``.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{key} must be a number, got {value!r:.40}")
    return float(value)


def recorded_int(value: object, key: str) -> int:
    """``value`` as an integer of a run record.

    Raises:
        ValueError: If it is not an integer, naming ``key``.
    """
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f"{key} must be an integer, got {value!r:.40}")
    return value
