"""``python -m agents.shac_chart``: chart SHAC runs' validations
(:mod:`agents.evaluation.shac_chart`).

Usage::

    python -m agents.shac_chart RUN [RUN ...] --out FILE.png [--overwrite]

Each RUN is an ``agents.shac`` run folder. Every run is read and checked before anything
is written; an existing ``--out`` is replaced only with ``--overwrite``. Refusals exit
with status 2 and one line naming the argument.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from agents.artifacts import files
from agents.commands import options as cli
from agents.evaluation.shac_chart import read_shac_curve, write_shac_chart


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.shac_chart"),
        description="Chart SHAC runs: the mean action's and the noisy actor's validation "
        "rates, and the share of mean actions past the bounds",
    )
    parser.add_argument("runs", nargs="+", type=Path, metavar="RUN", help="agents.shac run folders")
    parser.add_argument("--out", type=Path, required=True, metavar="FILE.png")
    cli.add_overwrite(parser, "replace --out")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (refusals exit with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        curves = [read_shac_curve(run) for run in args.runs]
    except (OSError, ValueError) as error:
        parser.error(f"argument RUN: {error}")
    if args.out.suffix != ".png":
        parser.error(f"argument --out: {args.out} is not a .png file")
    problem = files.outputs_problem(args.out.parent, (args.out.name,), args.overwrite)
    if problem is not None:
        parser.error(f"argument --out: {problem}")
    print(f"wrote {write_shac_chart(curves, args.out)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
