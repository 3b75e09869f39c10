"""``python -m agents.time_to_ceiling RESULTS_JSON``: the time-to-ceiling table of a
report's ``results.json`` (the computation: :mod:`agents.evaluation.time_to_ceiling`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from agents.artifacts import files
from agents.artifacts.results import ResultsDocument
from agents.commands import options as cli
from agents.evaluation.time_to_ceiling import time_to_ceiling_table


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.time_to_ceiling"),
        description="Gap to the certified ceiling and wall time of each scenario's best agent",
    )
    parser.add_argument("results", type=Path, help="results.json of python -m agents.report")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Print the table of a report's ``results.json``; exit 2 naming the file when it is
    not one."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        data = files.read_json(args.results, "results", allow_nan=True)
        if not isinstance(data, list):
            raise ValueError("not a list of results documents")
        documents = [
            ResultsDocument.from_json(item, f"{args.results}[{index}]")
            for index, item in enumerate(data)
        ]
        table = time_to_ceiling_table(documents)
    except ValueError as error:
        parser.error(f"argument results: {args.results} is not a report's results.json ({error})")
    print(table, end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
