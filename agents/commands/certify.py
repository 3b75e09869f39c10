"""``python -m agents.certify``: certify a scene's ceiling (:mod:`agents.oracles.certify`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from agents.artifacts.certificates import markdown, write_certificate
from agents.envs import ENV_IDS, check_env_id
from agents.oracles.certify import DEFAULT_RESTARTS, certify
from agents.oracles.planner import PlannerConfig


def parse_seeds(text: str) -> list[int]:
    """ "1000-1099" -> [1000, ..., 1099]; "5" -> [5]; "1,4,9" -> [1, 4, 9]."""
    seeds: list[int] = []
    for part in text.split(","):
        if "-" in part.strip()[1:]:
            first, last = part.strip().split("-", 1)
            low, high = int(first), int(last)
            if high < low:
                raise ValueError(f"empty seed range {part!r}")
            seeds.extend(range(low, high + 1))
        else:
            seeds.append(int(part))
    return seeds


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog="python -m agents.certify", description="Certify a scene's ceiling over seeds."
    )
    parser.add_argument("--env", default="trailer_env/Reverse-v1", choices=ENV_IDS,
                        metavar="ENV_ID", help=f"one of {', '.join(ENV_IDS)}")  # fmt: skip
    parser.add_argument("--n-trailers", type=int, default=2, help="number of trailers")
    parser.add_argument("--seeds", default="1000-1099", help="e.g. 1000-1099 (default)")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    parser.add_argument("--samples", type=int, default=PlannerConfig.samples)
    parser.add_argument("--iterations", type=int, default=PlannerConfig.iterations)
    parser.add_argument(
        "--restarts",
        type=int,
        default=DEFAULT_RESTARTS,
        help="plan the starts not kept safe again, up to this many times, with new planner "
        f"seeds (default {DEFAULT_RESTARTS})",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    env_id = check_env_id(args.env)
    if args.n_trailers < 0:
        parser.error(f"argument --n-trailers: must be >= 0, got {args.n_trailers}")
    try:
        seeds = parse_seeds(args.seeds)
        config = PlannerConfig(
            samples=args.samples,
            iterations=args.iterations,
            elites=min(PlannerConfig.elites, max(1, args.samples // 4)),
        )
    except ValueError as error:
        parser.error(str(error))
    if args.out.exists() and not args.overwrite:
        parser.error(f"argument --out: {args.out} exists; pass --overwrite to replace it")
    if args.restarts < 0:
        parser.error(f"argument --restarts: must be >= 0, got {args.restarts}")
    certificate = certify(env_id, args.n_trailers, seeds, config, restarts=args.restarts)
    write_certificate(certificate, args.out, args.overwrite)
    print(markdown(certificate).split("\n\n| seed")[0])
    print(f"wrote {args.out / 'certificate.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
