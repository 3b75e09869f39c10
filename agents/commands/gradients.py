"""The exact model's policy gradients against the horizon and n (the computation:
:mod:`agents.evaluation.gradients`).

Usage::

    python -m agents.gradients --n 1-8 --starts 64 --out docs/generated/gradients

For each n and each of the two policies (``lqr``: the LQR's gains; ``zero``: no feedback),
the H-step return of every start is differentiated through the differentiable twin with
respect to that start's feedback gains, for H = 1, 2, 4, ..., ``--max-horizon``. Writes
``gradients.md``, ``gradients.json`` and ``gradients.png`` into ``--out``, atomically;
existing files are replaced only with ``--overwrite``. ``--redraw`` writes the table and
the chart again from ``--out``'s ``gradients.json`` (checked whole first).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from agents.commands import options as cli
from agents.evaluation.gradients import OUTPUTS, redraw, write_gradients
from agents.progress import duration
from agents.seeds import TUNING_SEED


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.gradients"),
        description=(__doc__ or "").split("\n")[0],
    )
    parser.add_argument(
        "--n", type=cli.trailer_list, default=cli.trailer_list("1-8"), help="e.g. 1-8"
    )
    parser.add_argument(
        "--starts", type=cli.at_least(2, 1024), default=64, help="starts per cell (2 .. 1024)"
    )
    parser.add_argument(
        "--max-horizon",
        type=cli.at_least(1, 1024),
        default=256,
        help="the longest horizon H in control steps (H = 1, 2, 4, ... up to it; at most 1024)",
    )
    cli.add_seed(parser, TUNING_SEED, "first start's seed (default: the tuning seeds)")
    parser.add_argument("--out", type=Path, default=cli.OUT_ROOT / "gradients")
    cli.add_overwrite(parser, "replace an earlier run's files")
    parser.add_argument(
        "--redraw",
        action="store_true",
        help="write the table and the chart again from --out's gradients.json (no measuring)",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.redraw:
        if not (args.out / OUTPUTS[1]).is_file():
            parser.error(f"argument --redraw: no {OUTPUTS[1]} in {args.out}")
        try:
            print(redraw(args.out), end="")
        except ValueError as error:
            parser.error(f"argument --redraw: {error}")
        return 0
    cli.check_out_options(parser, args, OUTPUTS, args.starts)
    horizons = [2**k for k in range(args.max_horizon.bit_length()) if 2**k <= args.max_horizon]
    started = time.perf_counter()
    table = write_gradients(args.out, args.n, horizons, args.starts, args.seed)
    print(table, end="")
    print(f"wrote {args.out} in {duration(time.perf_counter() - started)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
