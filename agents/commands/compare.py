"""``python -m agents.compare``: one compact table from several ``agents.evaluate`` outputs
(the computation: :mod:`agents.evaluation.compare`).

Usage::

    python -m agents.compare "LABEL=DIR" ["LABEL=DIR" ...] --out FILE.md [--overwrite]

Each DIR is an ``agents.evaluate`` output folder, under the column LABEL (folders under
one label share the column); a row per policy, a cell its headline rate. Refusals exit
with status 2 and one line before anything is written: an argument without ``=``, a
folder without a readable ``results.json``, one policy twice in a column, evaluations of
different scenes, an --out that exists without ``--overwrite``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from agents.artifacts import files
from agents.commands import options as cli


def column(text: str) -> tuple[str, Path]:
    """``LABEL=DIR`` as (label, folder)."""
    label, sep, folder = text.partition("=")
    if not sep or not label.strip() or not folder:
        raise argparse.ArgumentTypeError(f"expected LABEL=DIR, got {text!r}")
    return label.strip(), Path(folder)


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.compare"),
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("columns", nargs="+", type=column, metavar="LABEL=DIR")
    parser.add_argument("--out", type=Path, required=True, metavar="FILE.md")
    cli.add_overwrite(parser, "replace --out")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; bad arguments exit with 2 before anything is written."""
    parser = build_parser()
    args = parser.parse_args(argv)
    from agents.evaluation.compare import markdown, read_evaluation

    if args.out.exists() and not args.overwrite:
        parser.error(f"--out: {args.out} exists; pass --overwrite to replace it")
    cli.check_out_file(parser, args.out, "--out")
    try:
        columns = [(label, folder, read_evaluation(folder)) for label, folder in args.columns]
        table = markdown(columns)
    except ValueError as error:
        parser.error(str(error))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    files.atomic_write_text(args.out, table)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
