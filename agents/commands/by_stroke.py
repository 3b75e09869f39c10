"""Where policies lose: the headline rate against the screen stroke each start needs (the
computation: :mod:`agents.evaluation.by_stroke`).

Usage::

    python -m agents.by_stroke --env trailer_env/Reverse-v1 --n-trailers 3 \\
        --policy ppo_reverse_v1_n3 dagger_reverse_v1_n3 lqr --edges 0.5,0.6,0.7 \\
        [--out FOLDER] [--overwrite]

Every ``--policy`` plays the committed certificate's starts; the table counts, per band
of screen stroke (``--edges``, shares of ``s_max``), the starts, the feasible ones and
those each policy saves, then names the starts every policy loses. Printed, and with
``--out`` written as ``by_stroke.md`` and ``by_stroke.json``, atomically (existing files
are replaced only with ``--overwrite``).
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
from pathlib import Path

from agents.artifacts import files
from agents.commands import options as cli
from agents.envs import HEADLINE_ENV_ID
from agents.evaluation.by_stroke import OUTPUTS, by_stroke


def band_edges(text: str) -> list[float]:
    """``--edges``: increasing finite numbers separated by commas."""
    try:
        edges = [float(part) for part in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected numbers separated by commas; got {text[:40]!r}"
        ) from None
    if not all(map(math.isfinite, edges)) or any(b <= a for a, b in itertools.pairwise(edges)):
        raise argparse.ArgumentTypeError(
            f"the edges must be finite and increasing; got {text[:40]!r}"
        )
    return edges


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.by_stroke"),
        description="The headline rate against the screen stroke each start needs",
    )
    cli.add_env(parser, HEADLINE_ENV_ID)
    parser.add_argument("--n-trailers", type=cli.at_least(0), required=True)
    parser.add_argument(
        "--policy", nargs="+", required=True, help="policy specs, as agents.evaluate's"
    )
    parser.add_argument(
        "--edges", type=band_edges, default=[0.5, 0.6, 0.7], help="band edges (default 0.5,0.6,0.7)"
    )
    parser.add_argument("--out", type=Path, default=None, help="also write the table here")
    cli.add_overwrite(parser, "replace by_stroke.md and .json in --out")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; bad arguments exit with 2 before any episode runs."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.out is not None:
        cli.check_out_folder(parser, args.out, files_in=OUTPUTS)
        existing = [name for name in OUTPUTS if (args.out / name).exists()]
        if existing and not args.overwrite:
            parser.error(
                f"argument --out: {args.out} holds {', '.join(existing)}; pass --overwrite"
            )
    try:
        table = by_stroke(args.env, args.n_trailers, args.policy, args.edges)
    except ValueError as error:
        parser.error(str(error))
    text = table.markdown()
    sys.stdout.write(text)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        files.atomic_write_text(args.out / OUTPUTS[0], text)
        files.write_json(args.out / OUTPUTS[1], table.to_json())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
