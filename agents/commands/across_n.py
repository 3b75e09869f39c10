"""The headline rate against the number of trailers: policies, specialists, the LQR and the
certified ceiling on one scene, n by n (the computation: :mod:`agents.evaluation.across_n`).

Usage::

    python -m agents.across_n --env trailer_env/Reverse-v1 --n 1-6 \\
        --policy dagger_reverse_v1_sequence lqr lqr-adaptive \\
        --specialist dagger_reverse_v1_n{n} --episodes 100 --out docs/generated/across_n

Each ``--policy`` is evaluated on every n it accepts (a model padded to three trailers
refuses four: its cell says so), ``--specialist`` names one model per n (``{n}`` in the
spec, or a list as ``agents.imitate --expert-policy`` takes:
:class:`agents.policies.experts.PolicyExpertConfig`), evaluated on its own n where it exists,
and the ceiling is the committed certificate's share of the same starts
(:func:`agents.evaluation.ceiling.ceiling_fraction`). Every cell is the same episodes
(``--episodes`` from ``--seed``, the test seeds by default). Writes ``across_n.md`` (the
table), ``across_n.json`` (every figure) and ``across_n.png`` (the chart) into ``--out``,
atomically; existing files are replaced only with ``--overwrite``.
"""

from __future__ import annotations

import argparse
import time
from functools import partial

from agents.commands import options as cli
from agents.envs import headline_metric, scene_title
from agents.evaluation.across_n import OUTPUTS, markdown, plot, rates_across_n, write_outputs
from agents.seeds import TEST_SEED


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.across_n"),
        description="The headline rate against the number of trailers (table, JSON, chart)",
    )
    cli.add_count_options(parser, ["lqr", "lqr-adaptive"], "across_n")
    cli.add_episodes(parser, 100, "episodes per cell")
    cli.add_seed(parser, TEST_SEED, "first episode's seed")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; bad arguments exit with 2 before any episode runs."""
    parser = build_parser()
    args = parser.parse_args(argv)
    cli.check_count_options(parser, args, OUTPUTS, args.episodes)
    started = time.perf_counter()
    lines = rates_across_n(args.env, args.n, args.policy, args.specialist, args.episodes, args.seed)
    seeds = f"seeds {args.seed}..{args.seed + args.episodes - 1}"
    fields: dict[str, object] = {
        "env_id": args.env,
        "episodes": args.episodes,
        "seed": args.seed,
        "metric": headline_metric(args.env),
    }
    title = f"{scene_title(args.env)}: {args.episodes} episodes per n ({seeds})"
    draw = partial(plot, lines, args.n, title=title)
    write_outputs(args.out, OUTPUTS, lines, fields, markdown(lines, args.n), draw, started)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
