"""The gains policies apply at the straight convoy, trailer by trailer, n by n (the
computation: :mod:`agents.evaluation.gains`).

Usage::

    python -m agents.gains --env trailer_env/Reverse-v1 --n 1-6 \\
        --policy lqr distill_reverse_v1_sequence16 distill_reverse_v1_sequence \\
        --specialist "1-3=ppo_reverse_v1_n{n},dagger_reverse_v1_n{n}" --out docs/generated/gains

Each gain is a central difference of the policy's action on the start ``--seed`` with
every hitch angle set to zero. ``--policy`` specs are evaluated at every n they accept (a
cell says why when refused); ``--specialist`` names one model per n as
``python -m agents.across_n`` takes it. Writes ``gains.md`` (one table per n),
``gains.json`` (every gain) and ``gains.png`` (one panel per n, gain against trailer)
into ``--out``, atomically; existing files are replaced only with ``--overwrite``.
"""

from __future__ import annotations

import argparse
import time
from functools import partial

from agents.commands import options as cli
from agents.envs import scene_title
from agents.evaluation.across_n import write_outputs
from agents.evaluation.gains import OUTPUTS, STEP, gains_across_n, markdown, plot
from agents.seeds import TEST_SEED


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.gains"),
        description="The gains policies apply at the straight convoy, trailer by trailer, "
        "n by n (table, JSON, chart)",
    )
    cli.add_count_options(parser, ["lqr"], "gains")
    cli.add_seed(parser, TEST_SEED, "the start whose other features are used")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; bad arguments exit with 2 before any policy is loaded."""
    parser = build_parser()
    args = parser.parse_args(argv)
    cli.check_count_options(parser, args, OUTPUTS, episodes=1)
    started = time.perf_counter()
    lines = gains_across_n(args.env, args.n, args.policy, args.specialist, args.seed)
    fields: dict[str, object] = {
        "env_id": args.env,
        "seed": args.seed,
        "step": STEP,
        "meaning": "d action / d alpha_k at the straight convoy, k = 1 behind the cart",
    }
    title = f"{scene_title(args.env)}: gains at the straight convoy (start {args.seed})"
    draw = partial(plot, lines, args.n, title=title)
    write_outputs(args.out, OUTPUTS, lines, fields, markdown(lines, args.n), draw, started)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
