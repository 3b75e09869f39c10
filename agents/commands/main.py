"""The main job: the committed agent against the baselines and the planner on Reverse-v1 (n = 2).

Run with ``python -m agents.main [--out DIR] [--episodes K] [--planner | --no-planner]
[--retrain [--overwrite]] [--train-iterations I] [--train-episodes E]``.

1. Load the committed agents for ``trailer_env/Reverse-v1``, n = 2
   (``agents/models/*.zip`` whose card names that scene), or, when there are none
   (or with ``--retrain``), imitate the planner on a short budget (DAgger,
   :mod:`agents.training.imitate`) into ``<out>/run``; a run already there is replaced only
   with ``--overwrite``.
2. Evaluate them, the baselines (zero, random, LQR) and the planner on K seeded
   episodes (seeds 1000 .. 1000 + K - 1) in one native batch per policy; a committed
   agent's training seeds are evaluated too (the table's spread over seeds). The
   planner's row replays the committed certificate's action records (``mpc-replay``,
   no planning); ``--planner`` re-plans every episode instead (``mpc``, the
   expensive oracle), ``--no-planner`` leaves both out.
3. Print the comparison table and the ceiling (the certified share of these starts,
   :func:`agents.evaluation.ceiling.ceiling_note`), and write ``results.json``, ``results.md``,
   ``margins.png``, ``frames.png`` and ``curves.png`` to ``--out`` (default ``out/main``).

Progress goes to standard error, the table to standard output; the measured times
are in the docs (Agents: the main job).

``--out`` must be a writable folder with no symbolic link among the files written,
``--episodes`` at most 100,000; checked before anything runs. The short run is
locked while it writes (``<out>/run/.lock``) and every file is written atomically.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from agents.artifacts import files, limits
from agents.artifacts.paths import export_files, model_stem
from agents.artifacts.run_folder import clear_run, export_model, symlink_problem
from agents.artifacts.shipped import committed_models
from agents.commands import options as cli
from agents.envs import HEADLINE_ENV_ID, HEADLINE_N_TRAILERS, env_settings
from agents.evaluation.ceiling import ceiling_note
from agents.evaluation.pictures import write_pictures
from agents.evaluation.results import (
    curve_metric,
    default_baselines,
    evaluate_policies,
    results_document,
)
from agents.evaluation.tables import markdown_table, table_legend
from agents.policies.sb3 import limit_torch_threads
from agents.progress import duration, plural
from agents.seeds import TEST_SEED

#: The main job's scenario: the headline one.
ENV_ID, N_TRAILERS = HEADLINE_ENV_ID, HEADLINE_N_TRAILERS


#: Budget of the fallback training: DAgger iterations and convoys per iteration (about
#: 40 s on two cores; 85 % safe on the test seeds, n = 2).
SHORT_ITERATIONS = 2


SHORT_EPISODES = 64


#: ``--out``'s default: the main job's own folder (the other commands write beside it,
#: under ``out/<command>/``).
DEFAULT_OUT = cli.OUT_ROOT / "main"


#: The files written to --out (besides the short run's).
OUT_FILES = ("results.json", "results.md", "margins.png", "frames.png", "curves.png")


def short_run_files(out: Path) -> list[Path]:
    """What :func:`train_short` writes under ``out`` and would replace: its run, its export."""
    return [out / "run", *export_files(_short_export(out))]


def _short_export(out: Path) -> Path:
    return out / f"{model_stem('dagger', ENV_ID, N_TRAILERS)}.zip"


def train_short(
    out: Path,
    iterations: int = SHORT_ITERATIONS,
    episodes: int = SHORT_EPISODES,
    seed: int = 0,
    overwrite: bool = False,
) -> Path:
    """Imitate the planner on Reverse-v1 (n = 2) on a short budget; returns the exported model.

    Raises:
        FileExistsError: If ``out`` already holds such a run (or its export) and
            ``overwrite`` is false.
    """
    run_dir = out / "run"
    existing = [path for path in short_run_files(out) if path.exists()]
    if existing and not overwrite:
        raise FileExistsError(f"{existing[0]} exists; pass --overwrite to replace it")
    problem = symlink_problem(run_dir) or next(
        (
            f"{path} is a symbolic link"
            for path in export_files(_short_export(out))
            if path.is_symlink()
        ),
        None,
    )
    if problem is not None:
        raise files.UnsafeFileError(problem)
    with files.RunLock(run_dir):
        clear_run(run_dir)  # the earlier run's files only (nothing else in the folder)
        return _imitate_short(out, run_dir, iterations, episodes, seed, overwrite)


def _imitate_short(
    out: Path, run_dir: Path, iterations: int, episodes: int, seed: int, overwrite: bool
) -> Path:
    from agents.training.imitate import imitate
    from agents.training.imitation_config import ImitationConfig

    reason = "--retrain" if committed_models(ENV_ID, N_TRAILERS) else "no committed agent"
    print(
        f"{reason}: imitating the planner ({plural(iterations, 'DAgger iteration')} of "
        f"{plural(episodes, 'convoy')}) into {run_dir} ...",
        flush=True,
    )
    config = ImitationConfig(ENV_ID, N_TRAILERS, seed, iterations=iterations, episodes=episodes)
    imitate(config, run_dir)
    return export_model(run_dir, _short_export(out), overwrite=overwrite)


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.main"), description=(__doc__ or "").split("\n")[0]
    )
    parser.add_argument(
        "--out", type=Path, default=DEFAULT_OUT, help=f"output folder (default {DEFAULT_OUT})"
    )
    cli.add_episodes(parser, 100, "evaluation episodes (default 100)")
    planner_options = parser.add_mutually_exclusive_group()
    planner_options.add_argument(
        "--planner",
        action="store_true",
        help="re-plan every episode with the mpc planner (an oracle; minutes) instead of "
        "replaying its certified records",
    )
    planner_options.add_argument(
        "--no-planner", action="store_true", help="leave the planner's row out"
    )
    parser.add_argument(
        "--train-iterations",
        type=cli.at_least(1, 1000),
        default=SHORT_ITERATIONS,
        help=f"DAgger iterations when training (default {SHORT_ITERATIONS}, at most 1000)",
    )
    parser.add_argument(
        "--train-episodes",
        type=cli.at_least(1, limits.MAX_IMITATION_EPISODES),
        default=SHORT_EPISODES,
        help=f"convoys per DAgger iteration when training (default {SHORT_EPISODES}, "
        f"at most {limits.MAX_IMITATION_EPISODES:,})",
    )
    parser.add_argument(
        "--retrain", action="store_true", help="train a fresh agent even if committed ones exist"
    )
    cli.add_overwrite(
        parser, "with --retrain: replace the run (and exported model) already in --out"
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    cli.check_out_folder(parser, args.out, files_in=OUT_FILES)
    cli.check_seeds(parser, TEST_SEED, args.episodes)
    limit_torch_threads()
    started = time.perf_counter()
    models = [] if args.retrain else committed_models(ENV_ID, N_TRAILERS)
    if not models:
        existing = [path for path in short_run_files(args.out) if path.exists()]
        if existing and not args.overwrite:
            parser.error(
                f"argument --out: {existing[0]} holds an earlier run; pass --overwrite "
                "to replace it, or another --out"
            )
        problem = symlink_problem(args.out / "run")
        if problem is not None:
            parser.error(f"argument --out: {problem}")
        try:
            models = [
                train_short(
                    args.out, args.train_iterations, args.train_episodes, overwrite=args.overwrite
                )
            ]
        except files.FolderLockedError as error:
            parser.error(f"argument --out: {error}")
    env_kwargs = {"n_trailers": N_TRAILERS}
    env_settings(env_kwargs)
    planner = [] if args.no_planner else ["mpc" if args.planner else "mpc-replay"]
    specs = [*default_baselines(ENV_ID), *planner, *(str(path) for path in models)]
    evaluations = evaluate_policies(specs, ENV_ID, env_kwargs, args.episodes, TEST_SEED)
    args.out.mkdir(parents=True, exist_ok=True)
    document = results_document(evaluations, ENV_ID, env_kwargs, args.episodes, TEST_SEED)
    ceiling = ceiling_note(ENV_ID, N_TRAILERS, args.episodes, TEST_SEED)
    files.write_json(args.out / "results.json", document.replace(ceiling=ceiling).to_json())
    table = markdown_table(evaluations, curve_metric(ENV_ID))
    print(
        f"\n{ENV_ID}, n = {N_TRAILERS}: {plural(args.episodes, 'episode')}, seeds "
        f"{TEST_SEED}..{TEST_SEED + args.episodes - 1}; safe = never in the singular band "
        "(margin < 0.3), never folded, never slowed to 0.3 m/s\n"
    )
    legend = table_legend([ENV_ID])
    files.atomic_write_text(args.out / "results.md", f"{table}\n{ceiling}\n\n{legend}\n")
    print(table)
    print(ceiling + "\n")
    print(legend + "\n")
    for path in write_pictures(evaluations, ENV_ID, env_kwargs, args.out, TEST_SEED):
        print(f"wrote {path}")
    print(f"main job done in {duration(time.perf_counter() - started)}; results in {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
