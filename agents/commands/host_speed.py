"""``python -m agents.host_speed``: this machine's speed by the fixed benchmark every
training run records on its card (:mod:`agents.training.host_speed`), to set a card's wall
time against the machine at hand."""

from __future__ import annotations

import argparse
import json

from agents.commands import options as cli


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.host_speed"),
        description=(
            "Measure this machine's speed as training runs record it on their cards: "
            "environment steps per second and one PPO update (about a second)"
        ),
    )
    parser.add_argument(
        "--json", action="store_true", help="print the record as JSON (the card's 'host')"
    )
    cli.add_torch_threads(parser)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Print this machine's :class:`~agents.artifacts.cards.HostSpeed`."""
    args = build_parser().parse_args(argv)
    from agents.policies.sb3 import limit_torch_threads
    from agents.training.host_speed import measure_host_speed

    limit_torch_threads(args.torch_threads)
    host = measure_host_speed()
    if args.json:
        print(json.dumps(host.to_json(), indent=2))
    else:
        print(f"{host.summary()}; benchmark {host.benchmark}, {host.torch_threads} torch threads")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
