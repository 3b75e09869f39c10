"""How long the documented commands take: a first run with numba's cache empty, then a warm one.

Run with ``python -m benchmarks.timings [--only NAME ...] [--docs docs]``.

Each command of :data:`COMMANDS` runs twice in a fresh temporary folder (so it writes
nothing in the clone; the clone's code is imported through ``PYTHONPATH``), both times
with ``NUMBA_CACHE_DIR`` pointing at one fresh temporary cache: the first run compiles
every kernel it needs, as on a fresh install that skipped ``trailer-env --compile``, the
second finds them cached, as every later run does. Before each run the 1-minute load
average (``os.getloadavg``, what ``uptime`` shows) is recorded, since the machines these
figures come from are shared.

The measurements accumulate in ``timings.json`` (one record per command, replaced when
the command is measured again), and ``timings.md`` is the table written from it; the
docs include it (``docs/generated/timings.md``). Without ``--docs`` both go to
``--out`` (default ``out/``): no command rewrites a tracked file unless asked. Both
files are written atomically. ``--only`` takes names of :data:`COMMANDS`; by default
the commands marked quick run (a minute or two in all), ``--all`` runs every one
(about 25 minutes on two cores).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import shlex
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from agents.artifacts import files
from agents.envs import HEADLINE_ENV_ID, HEADLINE_N_TRAILERS

ROOT = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class Timed:
    """A documented command to time: its name, its words and whether it is quick."""

    name: str
    argv: tuple[str, ...]
    quick: bool
    what: str = ""


#: The commands of the README and docs/agents.md whose times the docs give.
COMMANDS: tuple[Timed, ...] = (
    Timed(
        "first-step",
        (
            "python",
            "-c",
            "import gymnasium as gym, trailer_env; "
            "env = gym.make('trailer_env/Reverse-v1'); env.reset(seed=0); "
            "env.step(env.action_space.sample())",
        ),
        True,
        "the first gym.make + step",
    ),
    Timed("compile", ("python", "-m", "trailer_env", "--compile"), True, "every kernel"),
    Timed("main", ("python", "-m", "agents.main"), True, "the main job"),
    Timed(
        "evaluate-video",
        (
            "python",
            "-m",
            "agents.evaluate",
            "--policy",
            "ppo_reverse_n2",
            "--episodes",
            "1",
            "--no-plots",
            "--video",
            "out/ppo_reverse_n2.mp4",
            "--overwrite",
        ),
        True,
        "one episode and its video",
    ),
    Timed(
        "evaluate-mpc",
        ("python", "-m", "agents.evaluate", "--policy", "mpc", "--episodes", "100"),
        False,
        "the planner on 100 episodes, Reverse-v1, n = 2",
    ),
    Timed(
        "main-retrain",
        ("python", "-m", "agents.main", "--retrain", "--overwrite"),
        False,
        "2 DAgger iterations of 64 convoys, then the main job",
    ),
    Timed("main-planner", ("python", "-m", "agents.main", "--planner"), False, "mpc re-plans"),
    Timed(
        "certify",
        (
            "python",
            "-m",
            "agents.certify",
            "--env",
            HEADLINE_ENV_ID,
            "--n-trailers",
            str(HEADLINE_N_TRAILERS),
            "--seeds",
            "1000-1099",
            "--out",
            "out/cert_v1_n2",
        ),
        False,
        "100 starts",
    ),
    Timed("report", ("python", "-m", "agents.report"), False, "11 scenarios, planner rows"),
)

NAMES = tuple(command.name for command in COMMANDS)


def load_average() -> float:
    """The 1-minute load average (``uptime``'s first figure)."""
    return os.getloadavg()[0]


def run_once(argv: Sequence[str], work: Path, cache: Path, timeout: float) -> dict[str, Any]:
    """Run ``argv`` in ``work`` with numba's cache in ``cache``: its wall time, the load
    before it and its exit status (``python`` is this interpreter).

    Raises:
        subprocess.TimeoutExpired: If it runs past ``timeout`` seconds.
    """
    words = [sys.executable if argv[0] == "python" else argv[0], *argv[1:]]
    environment = {
        **os.environ,
        "NUMBA_CACHE_DIR": str(cache),
        "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
        "MPLBACKEND": "Agg",
        "SDL_VIDEODRIVER": os.environ.get("SDL_VIDEODRIVER", "dummy"),
    }
    load = load_average()
    started = time.perf_counter()
    result = subprocess.run(
        words, cwd=work, env=environment, capture_output=True, text=True, timeout=timeout
    )
    return {
        "seconds": round(time.perf_counter() - started, 1),
        "load": round(load, 2),
        "status": result.returncode,
        "stderr_tail": result.stderr[-400:] if result.returncode else "",
    }


def measure(command: Timed, timeout: float = 3600.0) -> dict[str, Any]:
    """The first (empty numba cache) and the warm run of ``command``, each in its own
    temporary folder, as one record of ``timings.json``."""
    with tempfile.TemporaryDirectory(prefix="timings-") as scratch:
        cache = Path(scratch) / "numba-cache"
        runs = []
        for run in ("first", "warm"):
            work = Path(scratch) / run
            work.mkdir()
            runs.append(run_once(command.argv, work, cache, timeout))
    return {
        "name": command.name,
        "command": shlex.join(command.argv),
        "what": command.what,
        "first": runs[0],
        "warm": runs[1],
        "date": datetime.date.today().isoformat(),
        "machine": machine(),
    }


def machine() -> str:
    """ "2 CPUs, Linux x86_64, Python 3.11" ."""
    return (
        f"{os.cpu_count()} CPUs, {platform.system()} {platform.machine()}, "
        f"Python {platform.python_version()}"
    )


def duration(seconds: float) -> str:
    """ "9.8 s", "42 s", "3 min 05 s"."""
    if seconds < 60:
        return f"{seconds:.0f} s" if seconds >= 10 else f"{seconds:.1f} s"
    minutes, rest = divmod(round(seconds), 60)
    return f"{minutes} min {rest:02d} s"


def _cell(run: dict[str, Any]) -> str:
    if run["status"] != 0:
        return f"failed (exit {run['status']})"
    return f"{duration(run['seconds'])} (load {run['load']:.1f})"


def markdown(records: Sequence[dict[str, Any]]) -> str:
    """The table the docs include: one row per command of :data:`COMMANDS`, in its order,
    measured or not yet."""
    by_name = {record["name"]: record for record in records}
    lines = [
        "| command | what | first run (numba's cache empty) | warm run | measured |",
        "|---|---|---|---|---|",
    ]
    for command in COMMANDS:
        record = by_name.get(command.name)
        shown = (
            f"`{shlex.join(command.argv)}`"
            if command.name != "first-step"
            else ('`gym.make("trailer_env/Reverse-v1")`, `reset`, `step` (`python -c`)')
        )
        if record is None:
            pending = f"not measured yet: `python -m benchmarks.timings --only {command.name}`"
            lines.append(f"| {shown} | {command.what} | {pending} | - | - |")
            continue
        lines.append(
            f"| {shown} | {command.what} | {_cell(record['first'])} | {_cell(record['warm'])} "
            f"| {record['date']}, {record['machine']} |"
        )
    return (
        "Written by `python -m benchmarks.timings` (load: the 1-minute load average before "
        "the run, as `uptime` shows it; the machines are shared).\n\n" + "\n".join(lines) + "\n"
    )


def read_records(path: Path) -> list[dict[str, Any]]:
    """The records of an earlier ``timings.json`` (none when absent).

    Raises:
        ValueError: If the file is not a list of records with a name.
    """
    if not path.exists():
        return []
    records = json.loads(path.read_text())
    if not isinstance(records, list) or not all(
        isinstance(record, dict) and isinstance(record.get("name"), str) for record in records
    ):
        raise ValueError(f"{path}: expected a list of timing records with a name")
    return records


def merged(old: Sequence[dict[str, Any]], new: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """``old`` with the commands of ``new`` replaced (or added), in :data:`COMMANDS`' order;
    records of commands no longer listed are dropped."""
    by_name = {record["name"]: record for record in old}
    by_name.update({record["name"]: record for record in new})
    return [by_name[name] for name in NAMES if name in by_name]


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.timings", description=(__doc__ or "").split("\n")[0]
    )
    choice = parser.add_mutually_exclusive_group()
    choice.add_argument(
        "--only",
        nargs="+",
        choices=NAMES,
        metavar="NAME",
        help=f"these commands ({', '.join(NAMES)}); default: the quick ones",
    )
    choice.add_argument("--all", action="store_true", help="every command (about 25 minutes)")
    parser.add_argument(
        "--out", type=Path, default=Path("out"), help="timings.json and timings.md (default out)"
    )
    parser.add_argument(
        "--docs",
        type=Path,
        default=None,
        metavar="DIR",
        help="write DIR/generated/timings.json and .md instead (e.g. docs)",
    )
    parser.add_argument(
        "--timeout", type=float, default=3600.0, help="seconds per run (default 3600)"
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    folder = args.out if args.docs is None else args.docs / "generated"
    if folder.exists() and not folder.is_dir():
        parser.error(f"argument {'--out' if args.docs is None else '--docs'}: {folder} is a file")
    if not args.timeout > 0:
        parser.error(f"argument --timeout: must be > 0, got {args.timeout}")
    try:
        old = read_records(folder / "timings.json")
    except (ValueError, json.JSONDecodeError) as error:
        parser.error(f"argument --out: {error}")
    if args.all:
        chosen = list(COMMANDS)
    else:
        names = args.only or [command.name for command in COMMANDS if command.quick]
        chosen = [command for command in COMMANDS if command.name in names]
    new = []
    for command in chosen:
        print(f"timings: {command.name}: {shlex.join(command.argv)} ...", file=sys.stderr)
        record = measure(command, args.timeout)
        print(
            f"timings: {command.name}: first {_cell(record['first'])}, "
            f"warm {_cell(record['warm'])}",
            file=sys.stderr,
        )
        new.append(record)
    records = merged(old, new)
    folder.mkdir(parents=True, exist_ok=True)
    files.write_json(folder / "timings.json", records)
    files.atomic_write_text(folder / "timings.md", markdown(records))
    print(f"wrote {folder / 'timings.json'} and {folder / 'timings.md'}")
    return (
        0
        if all(record["first"]["status"] == record["warm"]["status"] == 0 for record in new)
        else 1
    )


if __name__ == "__main__":
    raise SystemExit(main())
