"""Learning curves of several runs over training seeds: a chart and a table.

Usage::

    python -m agents.curves runs/reverse_v1_n2_ppo_s0 runs/reverse_v1_n2_ppo_s1 --out out/curves
    python -m agents.curves runs --out out/curves --plateau 5,0.05 --level lqr=0.62

Each RUN is a run folder of ``agents.train`` (``config.json`` + ``evaluations.csv``)
or a folder of run folders (its subfolders holding both; an RLlib run, which has no
``evaluations.csv``, is passed over). Runs are grouped by
(scene, n, algorithm) over their training seeds (:mod:`agents.evaluation.learning_curves`);
``<out>/learning_curves.png`` draws each group's validation headline rate (safe for
Reverse, success otherwise) against env steps and against wall time, the mean over
seeds with the min-max band, and horizontal lines: the certified ceiling of the
scene's committed certificate (``agents/certificates/``; measured on the test starts
1000-1099, not the validation ones; ``--no-ceiling`` leaves it out) and every
``--level NAME=RATE`` (e.g. the LQR's validation rate). ``<out>/learning_curves.md``
tables the final and best rates over seeds and where each seed's curve settled for good
(``--plateau WINDOW,EPS``: its last WINDOW evaluations within EPS of their mean, from the
first evaluation after which every one stays within EPS of that level).

Everything is checked before anything is written (exit status 2 naming the
argument): every RUN is read, ``--out`` must be a writable folder and its two files
are replaced only with ``--overwrite``. Both files are written atomically.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from agents.artifacts.certificates import committed_certificate
from agents.artifacts.run_folder import CONFIG_FILE, CURVE_FILE
from agents.commands import options as cli
from agents.evaluation.learning_curves import (
    GroupKey,
    RunCurve,
    group_runs,
    read_run,
    write_learning_curves,
    write_problem,
)

CEILING = "certified ceiling (test starts)"


def _level(text: str) -> tuple[str, float]:
    name, equals, value_text = text.partition("=")
    try:
        value = float(value_text)
        valid = bool(equals and name.strip()) and math.isfinite(value) and 0.0 <= value <= 1.0
    except ValueError:
        valid = False
    if not valid:
        raise argparse.ArgumentTypeError(f"expected NAME=RATE with a rate in [0, 1], got {text!r}")
    return name.strip(), value


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.curves"),
        description="Learning curves of run folders over training seeds (chart + table).",
    )
    parser.add_argument(
        "runs", nargs="+", type=Path, metavar="RUN", help="run folders, or folders of run folders"
    )
    parser.add_argument(
        "--out", type=Path, default=Path("out/curves"), help="output folder (default out/curves)"
    )
    parser.add_argument(
        "--plateau",
        type=cli.plateau_rule,
        default=(5, 0.05),
        metavar="WINDOW,EPS",
        help="plateau rule: WINDOW evaluations within EPS of their mean (default 5,0.05)",
    )
    parser.add_argument(
        "--level",
        type=_level,
        action="append",
        default=[],
        metavar="NAME=RATE",
        help="a horizontal line on every panel (repeatable), e.g. lqr=0.62",
    )
    parser.add_argument(
        "--no-ceiling", action="store_true", help="no line for the committed certificate's ceiling"
    )
    cli.add_overwrite(parser, "replace the chart and table in --out")
    return parser


def _run_folders(parser: argparse.ArgumentParser, paths: list[Path]) -> list[Path]:
    """The run folders named, a folder of runs expanded to its runs."""
    folders: list[Path] = []
    for path in paths:
        if not path.is_dir():
            parser.error(f"argument RUN: {path} is not a folder")
        if (path / CONFIG_FILE).is_file():
            folders.append(path)
            continue
        inside = sorted(
            child
            for child in path.iterdir()
            if (child / CONFIG_FILE).is_file() and (child / CURVE_FILE).is_file()
        )
        if not inside:
            parser.error(f"argument RUN: {path} is not a run folder and holds none")
        folders.extend(inside)
    return folders


def levels_of(
    runs: list[RunCurve], given: list[tuple[str, float]], ceiling: bool
) -> dict[GroupKey, dict[str, float]]:
    """Each group's horizontal lines: the committed ceiling (when asked and there is
    one), then the given levels."""
    levels: dict[GroupKey, dict[str, float]] = {}
    for key in group_runs(runs):
        lines: dict[str, float] = {}
        counts = key[1]  # a generalist's range has no one certificate
        certificate = (
            committed_certificate(key[0], counts) if ceiling and isinstance(counts, int) else None
        )
        if certificate is not None:
            lines[CEILING] = certificate.ceiling
        lines.update(given)
        levels[key] = lines
    return levels


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2, with a message)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    runs = []
    for folder in _run_folders(parser, args.runs):
        try:
            runs.append(read_run(folder))
        except ValueError as error:
            parser.error(f"argument RUN: {error}")
    try:
        levels = levels_of(runs, args.level, not args.no_ceiling)
    except ValueError as error:
        parser.error(f"argument RUN: {error}")
    problem = write_problem(args.out, args.overwrite)
    if problem is not None:
        parser.error(f"argument --out: {problem}")
    window, eps = args.plateau
    chart, table = write_learning_curves(
        runs, args.out, window=window, eps=eps, levels=levels, overwrite=args.overwrite
    )
    print(table.read_text(), end="")
    print(f"wrote {chart} and {table} ({len(runs)} runs)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
