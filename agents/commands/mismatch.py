"""Ceilings and every policy's safe rate against the size of the parameter mismatch, and
the parameter that matters most at each n (the computation: :mod:`agents.evaluation.mismatch`).

Usage::

    python -m agents.mismatch --n 1-3 --episodes 100 --out docs/generated/mismatch

For each n and mismatch size (``--sizes``, % of nominal; 0 is the nominal physics) every
``--policy`` (``{n}`` in a spec is the count) plays ``--episodes`` test starts from
``--seed`` and as many fresh ones from ``--fresh-seed``; the ceiling is the committed
certificate's share of the test starts (``agents/certificates/reverse_v1_mismatch<size>_n<n>.json``,
``-`` where none is committed). Then each parameter is drawn alone in +-40 %. Writes
``mismatch.md``, ``mismatch.json`` and ``mismatch_n<n>.png`` (one chart per n) into
``--out``, atomically; existing files are replaced only with ``--overwrite``.
``--redraw`` measures nothing: it writes the table and the charts again from the
``mismatch.json`` in ``--out``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from agents.commands import options as cli
from agents.evaluation.mismatch import POLICIES, SIZES, redraw, write_mismatch
from agents.progress import duration
from agents.seeds import FRESH_SEED, TEST_SEED
from trailer_env.randomize import PRESETS


def _size(text: str) -> int:
    """A mismatch size with a preset (or 0)."""
    sizes = sorted(int(name.removeprefix("mismatch")) for name in PRESETS)
    try:
        size = int(text)
    except ValueError:
        size = -1
    if size != 0 and size not in sizes:
        raise argparse.ArgumentTypeError(f"a size is 0 or one of {sizes}, got {text!r}")
    return size


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.mismatch"),
        description=(__doc__ or "").split("\n")[0],
    )
    parser.add_argument(
        "--n", type=cli.trailer_list, default=cli.trailer_list("1-3"), help="e.g. 1-3"
    )
    parser.add_argument(
        "--sizes", type=_size, nargs="+", default=list(SIZES), help="mismatch sizes, %%"
    )
    parser.add_argument("--policy", nargs="+", default=list(POLICIES), metavar="SPEC")
    cli.add_episodes(parser, 100, "episodes per policy, n, size and seed set (default 100)")
    cli.add_seed(parser, TEST_SEED, "first test episode's seed")
    parser.add_argument(
        "--fresh-seed", type=cli.seed_value, default=FRESH_SEED, help="first fresh episode's seed"
    )
    parser.add_argument("--out", type=Path, default=cli.OUT_ROOT / "mismatch")
    parser.add_argument(
        "--redraw",
        action="store_true",
        help="write the table and charts again from --out's mismatch.json (measures nothing)",
    )
    cli.add_overwrite(parser, "replace an earlier run's files")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.redraw:
        try:
            print(redraw(args.out), end="")
        except (OSError, ValueError) as error:
            parser.error(f"argument --redraw: {error}")
        return 0
    outputs = ["mismatch.md", "mismatch.json", *(f"mismatch_n{n}.png" for n in args.n)]
    cli.check_out_options(parser, args, outputs, args.episodes)
    cli.check_seeds(parser, args.fresh_seed, args.episodes)
    started = time.perf_counter()
    sizes = sorted(set(args.sizes))
    table = write_mismatch(
        args.out, args.n, args.policy, sizes, args.episodes, args.seed, args.fresh_seed
    )
    print(table, end="")
    print(f"wrote {args.out} in {duration(time.perf_counter() - started)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
