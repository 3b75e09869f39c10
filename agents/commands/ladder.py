"""``python -m agents.ladder``: time to the certified ceiling against the number of
trailers, one point per measured training run (the computation:
:mod:`agents.evaluation.ladder`).

Usage::

    python -m agents.ladder --method PPO RUN [RUN ...] --method SAC RUN ... --out DIR

Each RUN is a run folder (``config.json`` and ``evaluations.csv``) or a committed model
(``.zip`` with its card and curve). Every RUN is read and checked before anything is
written. Writes ``ladder.json``, ``ladder.md`` and ``ladder.png`` into ``--out``,
atomically; existing files are replaced only with ``--overwrite``. ``--redraw`` writes the
table and the chart again from ``--out``'s ``ladder.json`` (checked whole first).
``--update --overwrite`` replaces only the points of the methods given (a method's runs
retrained), keeping every other point of ``--out``'s ``ladder.json``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from agents.commands import options as cli
from agents.evaluation.ladder import (
    BUDGET_MINUTES,
    DOCUMENT_FILE,
    GAP_POINTS,
    Ladder,
    markdown,
    read_ladder,
    read_point,
    write_ladder,
    write_problem,
)


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.ladder"),
        description="Time to the certified ceiling against n, one point per measured run",
    )
    parser.add_argument(
        "--method",
        nargs="+",
        action="append",
        metavar=("NAME", "RUN"),
        default=[],
        help="a method's name and its runs (run folders or committed models); repeat per method",
    )
    parser.add_argument(
        "--budget-minutes",
        type=float,
        default=BUDGET_MINUTES,
        help=f"wall time a point is read within (default {BUDGET_MINUTES:g})",
    )
    parser.add_argument("--out", type=Path, default=cli.OUT_ROOT / "ladder")
    cli.add_overwrite(parser, "replace an earlier ladder's files")
    parser.add_argument(
        "--update",
        action="store_true",
        help="replace only the points of the methods given, keeping the others of --out's "
        "ladder.json (with --overwrite; the budget must be that ladder's)",
    )
    parser.add_argument(
        "--redraw",
        action="store_true",
        help="write the table and the chart again from --out's ladder.json (no reading runs)",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.redraw:
        if args.method or args.update:
            parser.error("argument --redraw: it reads ladder.json, not --method's runs")
        try:
            ladder = read_ladder(args.out)
            write_ladder(ladder, args.out, overwrite=True)
        except ValueError as error:
            parser.error(f"argument --redraw: {error}")
        print(f"wrote {args.out} again from its {DOCUMENT_FILE}")
        return 0
    if not args.method:
        parser.error("give at least one --method NAME RUN [RUN ...]")
    if not 0 < args.budget_minutes <= 24 * 60:
        parser.error(f"argument --budget-minutes: must be in (0, 1440], got {args.budget_minutes}")
    names = [words[0] for words in args.method]
    for words in args.method:
        if len(words) < 2:
            parser.error(f"argument --method: {words[0]!r} has no run")
    if len(set(names)) != len(names):
        parser.error(f"argument --method: a method is given twice ({', '.join(names)})")
    points = []
    for name, *runs in args.method:
        for run in runs:
            try:
                points.append(read_point(name, Path(run), args.budget_minutes))
            except ValueError as error:
                parser.error(f"argument --method {name}: {error}")
    problem = write_problem(args.out, args.overwrite)
    if problem is not None:
        parser.error(f"argument --out: {problem}")
    if args.update:
        if not args.overwrite:
            parser.error("argument --update: it rewrites --out's ladder: add --overwrite")
        try:
            earlier = read_ladder(args.out)
        except ValueError as error:
            parser.error(f"argument --update: {error}")
        if earlier.budget_minutes != args.budget_minutes:
            parser.error(
                f"argument --update: --out's ladder reads its runs within "
                f"{earlier.budget_minutes:g} minutes, not {args.budget_minutes:g}"
            )
        replaced = set(names)
        kept = [point for point in earlier.points if point.method not in replaced]
        # The methods keep their order: a replaced one where it was, a new one last.
        order = list(dict.fromkeys([*earlier.methods, *names]))
        points = sorted([*kept, *points], key=lambda point: order.index(point.method))
    ladder = Ladder(budget_minutes=args.budget_minutes, gap_points=GAP_POINTS, points=tuple(points))
    write_ladder(ladder, args.out, overwrite=args.overwrite)
    print(markdown(ladder), end="")
    print(f"wrote {args.out} ({len(points)} runs)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
