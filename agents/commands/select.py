"""``python -m agents.select``: commit the best of a recipe's training seeds (the
computation: :mod:`agents.evaluation.selection`).

Usage::

    python -m agents.select RUN [RUN ...] --export agents/models/NAME.zip [--overwrite]

Each RUN is a finished run folder of ``agents.train`` or ``agents.imitate`` (its
``best_model.zip`` with its card), one per training seed, all of one scene, n, physics
and memory window. Every run's kept model plays the selection episodes (200 from seed
60,000, which no table uses) in the env its card records (one policy for a range of n at
each of its counts, its rate their mean); each is exported as
``<folder of NAME>/seeds/NAME_s<seed>.zip`` and the best as ``NAME.zip`` (ties to the lower
seed), its card recording every seed's rate. ``agents.rl_from_reward --export`` does the
same for runs it scores.

Refusals exit with status 2 and one line before anything is written: a RUN without a kept
model or a card, two runs of one training seed, runs of different scenes, n, physics or
windows, an export that is not a ``.zip`` or whose files exist without
``--overwrite``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from agents.artifacts.cards import read_model_card
from agents.artifacts.paths import export_files
from agents.artifacts.run_folder import BEST_MODEL
from agents.commands import options as cli


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.select"),
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("runs", nargs="+", type=Path, metavar="RUN")
    parser.add_argument("--export", type=Path, required=True, metavar="PATH.zip")
    cli.add_overwrite(parser, "replace the exported files")
    return parser


def _runs(parser: argparse.ArgumentParser, folders: list[Path]) -> dict[int, Path]:
    """Training seed to run folder; exit 2 on a run without a kept model or card, or two
    runs of one seed, or runs of different envs."""
    from agents.evaluation.selection import card_env, env_key

    runs: dict[int, Path] = {}
    envs = set()
    for folder in folders:
        model = folder / BEST_MODEL
        if not model.is_file():
            parser.error(f"RUN: {folder} has no {BEST_MODEL}")
        try:
            card = read_model_card(model)
            env_id, kwargs = card_env(model)
        except ValueError as error:
            parser.error(f"RUN: {error}")
        if card.seed is None:
            parser.error(f"RUN: {model}'s card records no training seed")
        if card.seed in runs:
            parser.error(f"RUN: {runs[card.seed]} and {folder} are both training seed {card.seed}")
        runs[card.seed] = folder
        envs.add(env_key(env_id, kwargs))
    if len(envs) != 1:
        parser.error("RUN: the runs' cards record different scenes, n, physics or windows")
    return runs


def main(argv: list[str] | None = None) -> int:
    """Entry point; bad arguments exit with 2 before anything is written."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.export.suffix != ".zip":
        parser.error("--export must name a .zip file")
    runs = _runs(parser, list(args.runs))
    seeds_dir = args.export.parent / "seeds"
    targets = [args.export] + [seeds_dir / f"{args.export.stem}_s{seed}.zip" for seed in runs]
    for target in targets:
        existing = [path for path in export_files(target) if path.exists()]
        if existing and not args.overwrite:
            parser.error(f"--export: {existing[0]} exists; pass --overwrite to replace it")
        for path in export_files(target):
            cli.check_out_file(parser, path, "--export")
    from agents.evaluation.selection import export_selected

    chosen, rates = export_selected(runs, args.export)
    for seed, rate in sorted(rates.items()):
        print(f"seed {seed}: {100 * rate:.1f} % on the selection episodes")
    print(f"exported seed {chosen} to {args.export} (every seed in {seeds_dir})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
