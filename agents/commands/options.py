"""Command-line pieces shared by the agents' commands (train, evaluate, main, report, ...).

The options every command spells the same way (``--env``, ``--n-trailers``, ``--seed``,
``--overwrite``, ``--trust-pickle``) and the number parsers behind them. A bad value
exits with status 2 and a message naming the argument (argparse's ``type`` contract:
the parsers raise :class:`argparse.ArgumentTypeError`). Every count is bounded (the
table of :mod:`agents.artifacts.limits`), and every output is checked writable before
any work (:func:`check_out_folder`, :func:`check_out_file`).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import re
import shlex
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TypeVar

from agents.artifacts import files, limits
from agents.envs import ENV_IDS

T = TypeVar("T")


def program(module: str) -> str:
    """The name the usage line shows: the console script that is running
    (``trailer-env-evaluate``), else ``python -m <module>``."""
    script = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else ""
    return script if script.startswith("trailer-env") else f"python -m {module}"


def _integer(text: str, minimum: int, expected: str, *, float_text: bool = False) -> int:
    """``text`` as an integer >= ``minimum``; ``float_text`` also takes "1e6" (not "1.5")."""
    try:
        value = int(float(text)) if float_text else int(text)
        valid = value >= minimum and (not float_text or value == float(text))
    except (ValueError, OverflowError):  # "abc", "nan"; "inf"
        valid = False
    if not valid:
        raise argparse.ArgumentTypeError(f"expected {expected}, got {text[:40]!r}")
    return value


def positive_int(text: str) -> int:
    """An integer >= 1, also written as a float with an integral value ("1e6")."""
    return _integer(text, 1, "a positive integer", float_text=True)


def non_negative_int(text: str) -> int:
    """An integer >= 0 (a seed, a step count that may be zero)."""
    return _integer(text, 0, "an integer >= 0")


def seed_value(text: str) -> int:
    """A seed: an integer in 0 .. 2**32 - 1."""
    value = _integer(text, 0, "an integer >= 0")
    if value > limits.MAX_SEED:
        raise argparse.ArgumentTypeError(f"must be <= {limits.MAX_SEED} (2**32 - 1), got {value}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def at_least(minimum: int, maximum: int | None = None) -> Callable[[str], int]:
    """A parser of integer counts >= ``minimum`` (and <= ``maximum``, when given)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected an integer >= {minimum}, got {text[:40]!r}"
            ) from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be >= {minimum}, got {value}")
        if maximum is not None and value > maximum:
            raise argparse.ArgumentTypeError(f"must be <= {maximum:,}, got {value:,}")
        return value

    parse.__name__ = f"integer >= {minimum}"  # argparse names the type in some messages
    return parse


def plateau_rule(text: str) -> tuple[int, float]:
    """``WINDOW,EPS``: a window of >= 2 evaluations and a band >= 0 (the plateau rule of
    :mod:`agents.evaluation.learning_curves`)."""
    window_text, comma, eps_text = text.partition(",")
    try:
        window, eps = int(window_text), float(eps_text)
        valid = bool(comma) and window >= 2 and math.isfinite(eps) and eps >= 0.0
    except ValueError:
        valid = False
    if not valid:
        raise argparse.ArgumentTypeError(
            f"expected WINDOW,EPS (an integer >= 2 and a number >= 0), got {text[:40]!r}"
        )
    return window, eps


def start_curriculum(text: str) -> tuple[float, int]:
    """``FROM,STEPS``: a start scale in (0, 1) and a step count >= 1 ("4e6" too), the
    schedule of :class:`agents.algorithms.options.start_curriculum.StartCurriculum`."""
    low_text, comma, steps_text = text.partition(",")
    try:
        low = float(low_text)
        steps = _integer(steps_text, 1, "", float_text=True) if comma else 0
        valid = bool(comma) and 0.0 < low < 1.0 and steps <= limits.MAX_TIMESTEPS
    except (ValueError, argparse.ArgumentTypeError):
        valid = False
    if not valid:
        raise argparse.ArgumentTypeError(
            f"expected FROM,STEPS (a scale in (0, 1) and a step count in 1 .. "
            f"{limits.MAX_TIMESTEPS:,}), got {text[:40]!r}"
        )
    return low, steps


def bounded(minimum: int, maximum: int) -> Callable[[str], int]:
    """A parser of integers in ``minimum .. maximum``, also written as "1e6"."""

    def parse(text: str) -> int:
        expected = "a positive integer" if minimum == 1 else f"an integer >= {minimum}"
        value = _integer(text, -(2**63), expected, float_text=True)
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be >= {minimum}, got {value}")
        if value > maximum:
            raise argparse.ArgumentTypeError(f"must be <= {maximum:,}, got {text[:40]}")
        return value

    parse.__name__ = f"integer in {minimum}..{maximum}"
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


def integer_range(
    text: str, minimum: int, maximum: int | None = None, *, proper: bool = False
) -> tuple[int, int]:
    """``N`` or ``LOW-HIGH`` as ``(low, high)`` (``N`` is ``(N, N)``), the one reader of
    "N-M" ranges (trailer counts, seeds): ``minimum <= LOW <= HIGH <= maximum`` (no upper
    bound when ``maximum`` is None); ``proper`` asks ``LOW < HIGH`` of a written range.

    Raises:
        ValueError: One line quoting ``text``: not ``N`` or ``LOW-HIGH`` of integers (a
            negative number included), ``LOW`` over ``HIGH``, or a bound crossed.
    """
    low_text, dash, high_text = text.strip().partition("-")
    example = f"{max(minimum, 1)}-{max(minimum, 1) + 2}"
    try:
        low = int(low_text)
        high = int(high_text) if dash else low
    except ValueError:
        raise ValueError(
            f"expected N or a range LOW-HIGH such as {example}, got {text[:40]!r}"
        ) from None
    top = "" if maximum is None else f" <= {maximum:,}"
    order = "<" if proper and dash else "<="
    if high < low or (order == "<" and high == low):
        raise ValueError(
            f"a range LOW-HIGH needs {minimum} <= LOW {order} HIGH{top}, got {text[:40]!r}"
        )
    if low < minimum or (maximum is not None and high > maximum):
        bounds = f">= {minimum}" if maximum is None else f"in {minimum}..{maximum:,}"
        raise ValueError(f"must be {bounds}, got {text[:40]!r}")
    return low, high


def integer_list(
    text: str, minimum: int, maximum: int, *, max_count: int, distinct: bool = True
) -> list[int]:
    """Comma-separated ``N`` and ``LOW-HIGH`` items (:func:`integer_range`) as one list in
    the order written: ``"1,4-6"`` -> ``[1, 4, 5, 6]``.

    Raises:
        ValueError: An empty text or item, a malformed item (:func:`integer_range`), more
            than ``max_count`` integers (counted before any list is built), or with
            ``distinct`` an integer written twice.
    """
    if not text.strip():
        raise ValueError(f"nothing given (e.g. {minimum}-{minimum + 2})")
    ranges = [integer_range(item, minimum, maximum) for item in text.split(",")]
    if sum(high - low + 1 for low, high in ranges) > max_count:
        raise ValueError(f"more than {max_count:,} integers in {text[:60]!r}")
    values = [value for low, high in ranges for value in range(low, high + 1)]
    if distinct and len(set(values)) != len(values):
        raise ValueError(f"an integer appears twice in {text[:60]!r}")
    return values


def argument_type(parse: Callable[[str], T], name: str) -> Callable[[str], T]:
    """``parse`` as an argparse ``type``: its ValueError becomes the argument's message
    (exit status 2 naming the option), ``name`` the type's name in argparse's messages."""

    def parse_argument(text: str) -> T:
        try:
            return parse(text)
        except ValueError as error:
            raise argparse.ArgumentTypeError(str(error)) from None

    parse_argument.__name__ = name
    return parse_argument


def trailer_counts(text: str) -> int | tuple[int, int]:
    """``--n-trailers``: ``N`` (>= 0) or ``LOW-HIGH`` (0 <= LOW < HIGH)."""
    try:
        low, high = integer_range(text, 0, proper=True)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return (low, high) if "-" in text.strip() else low


def add_n_trailers(
    parser: argparse.ArgumentParser, default: int = 2, *, ranges: bool = False
) -> None:
    """``--n-trailers N`` (>= 0); with ``ranges`` also ``LOW-HIGH`` (a generalist: every
    episode draws its n, :mod:`trailer_env.mixed`)."""
    parser.add_argument(
        "--n-trailers",
        type=trailer_counts if ranges else at_least(0),
        default=default,
        help=f"number of trailers (default {default})"
        + (", or a range LOW-HIGH (e.g. 1-3): a generalist" if ranges else ""),
    )


def add_randomize(parser: argparse.ArgumentParser, help: str) -> None:
    """``--randomize PRESET``: a preset of :data:`trailer_env.randomize.PRESETS` (default None)."""
    from trailer_env.randomize import PRESETS

    parser.add_argument("--randomize", choices=sorted(PRESETS), default=None, help=help)


def add_env_kwargs(parser: argparse.ArgumentParser) -> None:
    """``--set KEY=VALUE`` (repeatable): any ``gym.make`` keyword but ``n_trailers``."""
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="an environment keyword, repeatable: a ConvoyParams field (M=1.2, mu=0.4), dt, "
        "fidelity (fidelity=dopri5 or a JSON object), action_mode ...; VALUE is read as JSON "
        "when it parses, else as text",
    )


def env_kwargs_from(parser: argparse.ArgumentParser, args: argparse.Namespace) -> dict[str, object]:
    """``{"n_trailers": args.n_trailers, **--set}``, validated as ``gym.make`` would; exits 2
    naming ``--set`` (or ``--n-trailers``) and what is wrong (a value nested deeper than
    :data:`agents.artifacts.files.MAX_JSON_DEPTH` included)."""
    from agents.envs import env_settings

    kwargs: dict[str, object] = {"n_trailers": args.n_trailers}
    for item in getattr(args, "set", []):
        key, equals, text = item.partition("=")
        if not equals or not key.isidentifier():
            parser.error(f"argument --set: expected KEY=VALUE, got {item!r}")
        if key == "n_trailers":
            parser.error("argument --set: give n_trailers with --n-trailers")
        if key in kwargs:
            parser.error(f"argument --set: {key} given twice")
        depth = files.json_depth(text.encode("utf-8", "surrogateescape"))
        if depth > files.MAX_JSON_DEPTH:  # json.loads would end in a RecursionError
            parser.error(
                f"argument --set: {key}: the value is nested {depth} deep, over the limit of "
                f"{files.MAX_JSON_DEPTH}"
            )
        try:
            kwargs[key] = json.loads(text)
        except json.JSONDecodeError:
            kwargs[key] = text
    for flag, candidate in (("--n-trailers", {"n_trailers": args.n_trailers}), ("--set", kwargs)):
        try:
            env_settings(candidate)
        except (TypeError, ValueError) as error:
            parser.error(f"argument {flag}: {error}")
    return kwargs


def add_seed(parser: argparse.ArgumentParser, default: int, help: str) -> None:
    """``--seed S`` (0 .. 2**32 - 1; see :func:`check_seeds` for the episodes' seeds)."""
    parser.add_argument(
        "--seed",
        type=seed_value,
        default=default,
        help=f"{help}; at most 2**32 - 1",
    )


def add_episodes(
    parser: argparse.ArgumentParser,
    default: int,
    help: str,
    maximum: int = limits.MAX_EPISODES,
    flag: str = "--episodes",
) -> None:
    """``--episodes K`` (1 .. ``maximum``, default :data:`agents.artifacts.limits.MAX_EPISODES`)."""
    parser.add_argument(
        flag, type=bounded(1, maximum), default=default, help=f"{help}; at most {maximum:,}"
    )


def check_seeds(parser: argparse.ArgumentParser, seed: int, count: int) -> None:
    """Exit 2 when episodes ``seed .. seed + count - 1`` need seeds past 2**32 - 1."""
    problem = limits.seed_problem(seed, count)
    if problem is not None:
        parser.error(f"argument --seed: {problem}")


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


#: Where the commands' default output folders lie: ``out/<command>/<name>``.
OUT_ROOT = Path("out")
#: Longest name :func:`folder_name` returns.
MAX_FOLDER_NAME = 100


def folder_name(*parts: str) -> str:
    """A folder name of ``parts`` joined by ``_``: in each part every character but
    letters, digits and ``.=+-`` becomes ``-`` (runs of them one, none at either end),
    and a part left empty is left out (``default`` if all are); a name longer than
    :data:`MAX_FOLDER_NAME` is cut and ends in a digest of the whole (two long names
    stay apart)."""
    cleaned = [re.sub(r"[^A-Za-z0-9._=+-]+", "-", part).strip("-.") for part in parts]
    name = "_".join(part for part in cleaned if part) or "default"
    joined = "_".join(parts)
    if len(name) <= MAX_FOLDER_NAME:
        return name
    digest = hashlib.sha256(joined.encode("utf-8", "surrogateescape")).hexdigest()[:10]
    return f"{name[: MAX_FOLDER_NAME - 11].rstrip('-_.')}_{digest}"


def check_out_folder(
    parser: argparse.ArgumentParser, out: Path, name: str = "--out", files_in: tuple[str, ...] = ()
) -> None:
    """Exit 2 naming the argument when ``out`` could not be written as a folder (a file,
    a path through a file, no writable ancestor, a link) or one of ``files_in`` in it
    (the files the command will write there) is a symbolic link or a folder."""
    problem = files.writable_problem(out, folder=True)
    for name_in in files_in if problem is None else ():
        problem = problem or (
            files.writable_problem(out / name_in)
            if (out / name_in).exists() or (out / name_in).is_symlink()
            else None
        )
    if problem is not None:
        parser.error(f"argument {name}: {problem}")


def check_out_file(parser: argparse.ArgumentParser, path: Path, name: str) -> None:
    """Exit 2 naming the argument when the file ``path`` could not be written."""
    problem = files.writable_problem(path)
    if problem is not None:
        parser.error(f"argument {name}: {problem}")


def add_torch_threads(parser: argparse.ArgumentParser) -> None:
    """``--torch-threads T`` (1 .. 4 x the CPUs)."""
    top = limits.max_torch_threads()
    parser.add_argument(
        "--torch-threads",
        type=at_least(1, top),
        default=1,
        help=f"torch CPU threads (default 1, at most {top}: 4 per CPU)",
    )


def open_share(text: str) -> float:
    """A number strictly between 0 and 1 (a share, e.g. ``--start-replay``'s)."""
    try:
        share = float(text)
    except ValueError:
        share = float("nan")
    if not 0.0 < share < 1.0:
        raise argparse.ArgumentTypeError(f"expected a number in (0, 1), got {text[:40]!r}")
    return share


#: The most trailers ``--n`` of the analyses drawn n by n takes.
MAX_ANALYSIS_TRAILERS = 16


def trailer_list(text: str) -> list[int]:
    """``--n`` of the analyses drawn n by n: ``"1-6"``, ``"1,2,4"`` or both (``"1-3,6"``)
    as a sorted list of distinct counts in 1 .. :data:`MAX_ANALYSIS_TRAILERS`."""
    try:
        counts = integer_list(
            text, 1, MAX_ANALYSIS_TRAILERS, max_count=MAX_ANALYSIS_TRAILERS**2, distinct=False
        )
    except ValueError as error:
        raise argparse.ArgumentTypeError(f"counts of trailers: {error}") from None
    return sorted(set(counts))


def add_count_options(parser: argparse.ArgumentParser, policies: list[str], out: str) -> None:
    """The options of the analyses drawn n by n: --env, --n, --policy, --specialist,
    --out (default ``out/<out>``) and --overwrite."""
    from agents.envs import HEADLINE_ENV_ID

    add_env(parser, HEADLINE_ENV_ID)
    parser.add_argument("--n", type=trailer_list, default=trailer_list("1-6"), help="e.g. 1-6")
    parser.add_argument("--policy", nargs="+", default=policies, metavar="SPEC")
    parser.add_argument(
        "--specialist",
        default=None,
        metavar="SPEC",
        help="one model per n: {n} in the spec, or several comma-separated, each but one "
        "after its counts (1-3=ppo_reverse_v1_n{n},dagger_reverse_v1_n{n})",
    )
    parser.add_argument("--out", type=Path, default=OUT_ROOT / out)
    add_overwrite(parser, "replace an earlier run's files")


def check_count_options(
    parser: argparse.ArgumentParser, args: argparse.Namespace, outputs: Sequence[str], episodes: int
) -> None:
    """Exit 2, before anything runs, on a --specialist that names no model per n, then as
    :func:`check_out_options`."""
    from agents.evaluation.across_n import specialist_problem

    problem = specialist_problem(args.specialist)
    if problem is not None:
        parser.error(f"argument --specialist: {problem}")
    check_out_options(parser, args, outputs, episodes)


def check_out_options(
    parser: argparse.ArgumentParser, args: argparse.Namespace, outputs: Sequence[str], episodes: int
) -> None:
    """Exit 2, before anything runs, on a --seed that ``episodes`` would carry past the
    seeds' range, or an --out that cannot be written or holds ``outputs`` without
    --overwrite."""
    check_seeds(parser, args.seed, episodes)
    check_out_folder(parser, args.out, files_in=tuple(outputs))
    existing = [name for name in outputs if (args.out / name).exists()]
    if existing and not args.overwrite:
        parser.error(f"argument --out: {args.out} holds {', '.join(existing)}; pass --overwrite")


#: Characters a shell would read in a word: such a word is quoted (``{n}`` is not one).
_SHELL_SPECIAL = frozenset("()[]*?;&|<>$`'\"\\ \t!#~")


def shell_line(words: Sequence[str]) -> str:
    """``words`` as a line a shell runs as they are: a word with a character the shell
    would read (``median(A,B)``'s parentheses) is quoted, every other one left bare."""
    return " ".join(shlex.quote(word) if _SHELL_SPECIAL & set(word) else word for word in words)
