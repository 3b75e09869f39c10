"""Command-line pieces shared by the agents' commands (train, evaluate, main, report, ...).

The options every command spells the same way (``--env``, ``--n-trailers``, ``--seed``,
``--overwrite``, ``--trust-pickle``) and the number parsers behind them. A bad value
exits with status 2 and a message naming the argument (argparse's ``type`` contract:
the parsers raise :class:`argparse.ArgumentTypeError`).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path

from agents.envs import ENV_IDS


def _integer(text: str, minimum: int, expected: str, *, float_text: bool = False) -> int:
    """``text`` as an integer >= ``minimum``; ``float_text`` also takes "1e6" (not "1.5")."""
    try:
        value = int(float(text)) if float_text else int(text)
        valid = value >= minimum and (not float_text or value == float(text))
    except (ValueError, OverflowError):  # "abc", "nan"; "inf"
        valid = False
    if not valid:
        raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")
    return value


def positive_int(text: str) -> int:
    """An integer >= 1, also written as a float with an integral value ("1e6")."""
    return _integer(text, 1, "a positive integer", float_text=True)


def non_negative_int(text: str) -> int:
    """An integer >= 0 (a seed, a step count that may be zero)."""
    return _integer(text, 0, "an integer >= 0")


def positive_float(text: str) -> float:
    """A finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def at_least(minimum: int) -> Callable[[str], int]:
    """A parser of integer counts >= ``minimum`` (episodes, trailers, steps)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected an integer >= {minimum}, got {text!r}"
            ) from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be >= {minimum}, got {value}")
        return value

    parse.__name__ = f"integer >= {minimum}"  # argparse names the type in some messages
    return parse


def add_env(parser: argparse.ArgumentParser, default: str | None = None) -> None:
    """``--env ENV_ID``, one of the registered scenes (required when there is no default)."""
    parser.add_argument(
        "--env",
        required=default is None,
        default=default,
        choices=ENV_IDS,
        metavar="ENV_ID",
        help=f"environment id, one of {', '.join(ENV_IDS)}"
        + ("" if default is None else f" (default {default})"),
    )


def add_n_trailers(parser: argparse.ArgumentParser, default: int = 2) -> None:
    """``--n-trailers N`` (>= 0)."""
    parser.add_argument(
        "--n-trailers",
        type=at_least(0),
        default=default,
        help=f"number of trailers (default {default})",
    )


def add_seed(parser: argparse.ArgumentParser, default: int, help: str) -> None:
    """``--seed S`` (>= 0)."""
    parser.add_argument("--seed", type=non_negative_int, default=default, help=help)


def add_episodes(parser: argparse.ArgumentParser, default: int, help: str) -> None:
    """``--episodes K`` (>= 1)."""
    parser.add_argument("--episodes", type=at_least(1), default=default, help=help)


def add_overwrite(parser: argparse.ArgumentParser, help: str) -> None:
    """``--overwrite``: nothing a command wrote before is replaced without it."""
    parser.add_argument("--overwrite", action="store_true", help=help)


def add_trust_pickle(parser: argparse.ArgumentParser, what: str) -> None:
    """``--trust-pickle``: nothing is unpickled without it (:mod:`agents.artifacts`)."""
    parser.add_argument(
        "--trust-pickle",
        action="store_true",
        help=f"allow unpickling {what}: only for files you trust",
    )


def check_out_folder(parser: argparse.ArgumentParser, out: Path, name: str = "--out") -> None:
    """Exit 2 naming the argument when ``out`` exists and is not a folder."""
    if out.exists() and not out.is_dir():
        parser.error(f"argument {name}: {out} exists and is not a folder")
