"""The estimating baseline under mismatched physics: its estimation error against time,
and its safe rate beside the LQR designed for nominal and for the true parameters (the
computation: :mod:`agents.evaluation.estimation`).

Usage::

    python -m agents.estimation --n 1-3 --episodes 100 --out docs/generated/estimation

For each n, one episode of the headline scene with ``randomize="mismatch20"`` (seed
``--error-seed``) is driven by ``lqr-estimated``, and ``lqr``, ``lqr-adaptive`` and
``lqr-estimated`` are scored on the same ``--episodes`` seeded episodes from ``--seed``
(the test seeds by default). Writes ``estimation.md``, ``estimation.json`` and
``estimation.png`` into ``--out``, atomically; existing files are replaced only with
``--overwrite``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from agents.commands import options as cli
from agents.evaluation.estimation import OUTPUTS, write_estimation
from agents.progress import duration
from agents.seeds import TEST_SEED


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.estimation"),
        description=(__doc__ or "").split("\n")[0],
    )
    parser.add_argument(
        "--n", type=cli.trailer_list, default=cli.trailer_list("1-3"), help="e.g. 1-3"
    )
    cli.add_episodes(parser, 100, "episodes per policy and n (default 100)")
    cli.add_seed(parser, TEST_SEED, "first episode's seed")
    parser.add_argument(
        "--error-seed",
        type=cli.seed_value,
        default=TEST_SEED,
        help="the episode whose error is drawn",
    )
    parser.add_argument("--out", type=Path, default=cli.OUT_ROOT / "estimation")
    cli.add_overwrite(parser, "replace an earlier run's files")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    cli.check_out_options(parser, args, OUTPUTS, args.episodes)
    started = time.perf_counter()
    table = write_estimation(args.out, args.n, args.episodes, args.seed, args.error_seed)
    print(table, end="")
    print(f"wrote {args.out} in {duration(time.perf_counter() - started)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
