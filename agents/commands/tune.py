"""Search an algorithm's hyperparameters with Optuna; every trial a normal training run.

Usage (the ``tune`` extra: ``pip install 'trailer-env[tune]' -c constraints.txt``)::

    python -m agents.tune --env trailer_env/Reverse-v1 --algo ppo --n-trailers 2 \
        --timesteps 1e6 --trials 30 --out out/tune/reverse_v1_n2_ppo

Each trial samples the algorithm's search space (``agents/hyperparams/search.yml``, or
``--space``) over its hyperparameter file's entry and trains ``--timesteps`` steps in
``<out>/trials/trial_<k>/`` (a run folder of ``agents.train``, with its ``<algo>.yml``);
the objective is the validation headline rate averaged over the budget (the area under
the curve; :mod:`agents.training.tune` says why), or with ``--wall-budget SECONDS`` over
that much wall time (time to the plateau on this machine), the sampler TPE seeded with ``--seed``,
the pruner the median of the earlier trials at each evaluation. Progress and an ETA go
to standard error, one line per trial.

The study is ``<out>/study.log`` (an Optuna journal file): running the same command
again after a kill resumes it (``--trials`` counts all the study's trials; a last record
cut by the kill is dropped first, said on standard error; a journal damaged otherwise is
refused and left as it is). At the end
``<out>/best_trials.md`` and ``<out>/best_hyperparams.yml`` (the winner, in the format
of ``agents/hyperparams/<algo>.yml``) are written atomically. Everything is checked
before anything is written (exit status 2 naming the argument): the arguments, Optuna
being installed, the base file and the search space (every value it can sample,
against the algorithm's bounds), and ``--out``: a folder of another
search, a non-empty folder that holds no search or a finished search's results are
refused unless ``--overwrite`` (a search with other settings always).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from agents.algorithms import ALGOS
from agents.artifacts import files, limits
from agents.commands import options as cli
from agents.envs import scene_of
from agents.policies.sb3 import limit_torch_threads
from agents.training.tune import (
    BEST_HYPERPARAMS,
    BEST_TRIALS,
    SEARCH_SPACES,
    TuneSettings,
    read_space,
    require_optuna,
    search_problem,
    tune,
)


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.tune"),
        description="Hyperparameter search with Optuna (TPE, median pruner), resumable.",
    )
    cli.add_env(parser)
    parser.add_argument("--algo", required=True, choices=sorted(ALGOS), help="algorithm")
    cli.add_n_trailers(parser)
    parser.add_argument(
        "--timesteps",
        type=cli.bounded(1, limits.MAX_TIMESTEPS),
        default=1_000_000,
        help="steps per trial (default 1e6)",
    )
    parser.add_argument(
        "--trials",
        type=cli.bounded(1, 100_000),
        default=20,
        help="trials of the study in all, those of a resumed search included (default 20)",
    )
    cli.add_seed(parser, 0, "training seed of every trial and the sampler's seed (default 0)")
    parser.add_argument(
        "--n-envs",
        type=cli.bounded(1, limits.MAX_N_ENVS),
        default=None,
        help="environments per trial (default: the hyperparameter file's)",
    )
    parser.add_argument(
        "--eval-freq",
        type=cli.bounded(1, limits.MAX_TIMESTEPS),
        default=None,
        help="steps between validation evaluations (default: timesteps / 10)",
    )
    cli.add_episodes(
        parser, 50, "validation episodes per evaluation (default 50)", flag="--eval-episodes"
    )
    parser.add_argument(
        "--wall-budget",
        type=cli.positive_float,
        default=None,
        metavar="SECONDS",
        help="average the curve over this many seconds of wall time instead of over the "
        "steps; each trial stops at its first evaluation past it (run the search alone)",
    )
    parser.add_argument(
        "--startup-trials",
        type=cli.non_negative_int,
        default=5,
        help="complete trials before the pruner prunes (default 5)",
    )
    parser.add_argument(
        "--hyperparams",
        type=Path,
        default=None,
        help="folder of the base <algo>.yml (default agents/hyperparams)",
    )
    parser.add_argument(
        "--space",
        type=Path,
        default=SEARCH_SPACES,
        help="search-space file (default agents/hyperparams/search.yml)",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="the search's folder (default out/tune/<scene>_n<n>_<algo>)",
    )
    cli.add_overwrite(
        parser,
        f"search in a non-empty folder; replace {BEST_TRIALS} and "
        f"{BEST_HYPERPARAMS} of a finished search (and add trials to it)",
    )
    cli.add_torch_threads(parser)
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2, with a message)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        require_optuna()
    except ImportError as error:
        parser.error(str(error))
    command = ["python", "-m", "agents.tune", *(sys.argv[1:] if argv is None else argv)]
    settings = TuneSettings(
        env_id=args.env,
        algo=args.algo,
        n_trailers=args.n_trailers,
        budget=args.timesteps,
        seed=args.seed,
        n_envs=args.n_envs,
        eval_freq=args.eval_freq,
        eval_episodes=args.eval_episodes,
        hyperparams=args.hyperparams,
        space=args.space,
        startup_trials=args.startup_trials,
        wall_budget=args.wall_budget,
        command=tuple(command),
    )
    try:
        settings.base_entry()
    except (FileNotFoundError, KeyError, ValueError) as error:
        text = str(error.args[0]) if isinstance(error, KeyError) else str(error)
        parser.error(f"argument --hyperparams: {text}")
    try:
        read_space(args.algo, args.space)
    except ValueError as error:
        parser.error(f"argument --space: {error}")
    out = args.out or Path("out/tune") / f"{scene_of(args.env)}_n{args.n_trailers}_{args.algo}"
    problem = search_problem(out, settings, args.overwrite)
    if problem is not None:
        parser.error(f"argument --out: {problem}")
    limit_torch_threads(args.torch_threads)
    try:
        study = tune(
            settings, out, args.trials, overwrite=args.overwrite, verbose=0 if args.quiet else 1
        )
    except files.FolderLockedError as error:
        parser.error(f"argument --out: {error}")
    print((out / BEST_TRIALS).read_text(), end="")
    best = out / BEST_HYPERPARAMS
    print(f"{len(study.trials)} trials in {out}; best: {best if best.is_file() else 'none'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
