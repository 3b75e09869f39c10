"""The reinforcement-learning-from-reward table: training runs scored on the test protocol
(the computation: :mod:`agents.evaluation.rl_from_reward`).

Usage::

    python -m agents.rl_from_reward RUN [RUN ...] [--out docs/generated] \\
        [--fresh-seed 7000] [--fresh-episodes 200] [--overwrite]

Each RUN is a run folder of ``agents.train`` (or a folder of them). Per run, its kept
model (``best_model.zip``: the best validation evaluation) and its last model
(``final_model.zip``) are scored on the test episodes (seeds 1000..1099) and on
``--fresh-episodes`` fresh ones from ``--fresh-seed`` (disjoint from the training,
validation and test seeds), with the scene's headline rate (safe on Reverse, success
on the goal scenes). The validation curve gives where the run settled on its final
plateau (:func:`agents.evaluation.learning_curves.final_plateau`: its last five
evaluations within 0.05 of their mean, and every evaluation since the settling point
too), or that its end is not flat, and whether its end still climbs
(:func:`~agents.evaluation.learning_curves.trend`: the rise of the least-squares line
through the evaluations of its last third of steps, ± its standard error: the plateau
rule seldom passes
a flat curve near 0.8 measured on 50 episodes, while the trend asks only whether the end
still climbs). Runs of one (scene, n, algorithm) over training seeds are summarised as
mean ± sd.

Writes ``rl_from_reward.md`` (one table per (scene, n), one row per run and per
group) and ``rl_from_reward.json`` (every figure), atomically; existing files are
replaced only with ``--overwrite``. ``--update`` adds the RUNs to the table already in
``--out`` instead: its rows of other runs are kept as they were scored (run folders are
not kept forever), a RUN of the same scene, n, recipe and training seed as a row is
re-scored in that row's place (whatever its folder's name); the fresh seeds must match.
A kept row's trend is computed again from its kept curve (below), when there is one,
so rows scored before the trend column existed get theirs.

``--export agents/models/NAME.zip`` (all RUNs of one scene, n and algorithm) commits
the runs as the project commits a learned agent: each run's kept model goes to
``agents/models/seeds/NAME_s<seed>.zip`` and the one with the best headline rate on the
selection episodes (200 from seed 60,000, which no table uses; ties to the lower seed)
to ``NAME.zip``, its card recording the selection.

Run folders are working files, not kept with the table, so every scored run's curve (its
``config.json`` and ``evaluations.csv``) is copied to
``<out>/rl_runs/<scene>_n<n>_<recipe>_s<seed>/`` (named by the row's identity: a
re-scored run replaces its own); ``python -m agents.curves <out>/rl_runs/...`` redraws
the charts from there.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from agents.commands import options as cli
from agents.evaluation.learning_curves import counts_text, group_runs, read_run
from agents.evaluation.rl_from_reward import (
    CURVES,
    DOCUMENT,
    TABLE,
    TEST_EPISODES,
    RunScore,
    export_selected,
    kept_scores,
    merge_scores,
    run_folders,
    score_run,
    write_table,
)
from agents.seeds import TEST_SEED


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.rl_from_reward"),
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("runs", nargs="+", type=Path, metavar="RUN")
    parser.add_argument("--out", type=Path, default=cli.OUT_ROOT / "rl_from_reward")
    parser.add_argument("--fresh-seed", type=cli.seed_value, default=7000)
    cli.add_episodes(parser, 200, "fresh episodes per model", flag="--fresh-episodes")
    parser.add_argument("--export", type=Path, default=None, metavar="PATH.zip")
    cli.add_overwrite(parser, "replace the table in --out")
    parser.add_argument(
        "--update", action="store_true", help="add to the table in --out (see above)"
    )
    return parser


def _check(parser: argparse.ArgumentParser, args: argparse.Namespace, folders: list[Path]) -> None:
    """Exit 2, before any run is scored, on fresh episodes that overlap the test seeds,
    no finished run, a table in --out without --overwrite or --update, runs of a range of
    n, or an --export that does not take one group of runs into a new .zip."""
    if (
        args.fresh_seed < TEST_SEED + TEST_EPISODES
        and args.fresh_seed + args.fresh_episodes > TEST_SEED
    ):
        parser.error("--fresh-seed: the fresh episodes overlap the test seeds")
    cli.check_seeds(parser, args.fresh_seed, args.fresh_episodes)
    if not folders:
        parser.error("no finished run folder (config.json, best and final model) in RUN")
    existing = (args.out / TABLE).exists() or (args.out / DOCUMENT).exists()
    if not args.update and not args.overwrite and existing:
        parser.error(f"{args.out} already holds a table: --overwrite replaces it (--update adds)")
    groups = group_runs([read_run(folder) for folder in folders])  # refuses unreadable runs
    ranges = [f"{key[0]} n = {counts_text(key[1])}" for key in groups if isinstance(key[1], tuple)]
    if ranges:
        parser.error(
            f"RUN: {ranges[0]} is one policy for a range of n; this table scores one n "
            "(score it on each n with agents.evaluate)"
        )
    if args.export is not None:
        if len(groups) != 1:
            parser.error(
                f"--export takes the runs of one scene, n and algorithm, got {len(groups)}"
            )
        if args.export.suffix != ".zip":
            parser.error("--export must name a .zip file")
        if args.export.exists() and not args.overwrite:
            parser.error(f"{args.export} exists; pass --overwrite to replace it")


def main(argv: list[str] | None = None) -> int:
    """Entry point; bad arguments exit with 2 before any run is scored."""
    parser = build_parser()
    args = parser.parse_args(argv)
    folders = run_folders(args.runs)
    _check(parser, args, folders)
    kept: list[RunScore] = []
    if args.update:
        try:
            kept = kept_scores(args.out / DOCUMENT, args.fresh_seed, args.fresh_episodes)
        except ValueError as error:
            parser.error(f"--update: {error}")
    scored = []
    for index, folder in enumerate(folders, 1):
        print(f"[{index}/{len(folders)}] scoring {folder}", file=sys.stderr, flush=True)
        scored.append(score_run(folder, args.fresh_seed, args.fresh_episodes))
    scores = merge_scores(kept, scored) if kept else scored
    table, document = write_table(
        args.out,
        scores,
        list(zip(folders, scored, strict=True)),
        args.fresh_seed,
        args.fresh_episodes,
    )
    print(f"wrote {table}, {document} and {len(scored)} curves in {args.out / CURVES}")
    if args.export is not None:
        chosen = export_selected(scored, folders, args.export)
        print(f"exported seed {chosen} to {args.export} (siblings in agents/models/seeds/)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
