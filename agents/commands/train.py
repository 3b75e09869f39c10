"""Train a stable-baselines3 agent on a trailer_env scene through the native batched env.

Usage::

    python -m agents.train --env trailer_env/Reverse-v0 --algo ppo --n-trailers 2 \
        --timesteps 1000000 --seed 0

Hyperparameters come from ``agents/hyperparams/<algo>.yml`` (rl-zoo3 format). The
run folder (default ``runs/<scene>_n<n>_<algo>_s<seed>``) receives:

* ``config.json``: the run's record (:class:`agents.training.config.TrainConfig`), the
  base of every model card;
* ``evaluations.csv``: the learning curve (periodic seeded safety evaluations);
* ``best_model.zip``, ``final_model.zip``, each with its card (``.json``) and, when the
  hyperparameters normalise observations, its statistics (``*_vecnormalize.json``);
* ``checkpoints/<algo>_<steps>_steps.zip`` (and the replay buffer for SAC/TD3);
* ``logs/``: SB3's training statistics (CSV; TensorBoard too when installed).

``--n-trailers LOW-HIGH`` trains one policy for a range of trailer counts (a generalist:
every episode draws its n, and the policy reads the observation padded to HIGH trailers
with the trailer mask, :mod:`trailer_env.mixed`; default folder ``runs/<scene>_n1-3_...``);
``--randomize PRESET`` draws the physics per episode (:mod:`trailer_env.randomize`). Both
go over the file's ``env_kwargs`` and into the cards, so ``agents.evaluate`` plays such a
model on any n of its range. Shaping needs one n (its potential is one n's LQR).

``--resume <checkpoint.zip>`` continues a run: the timestep count goes on from the
checkpoint's and ``--timesteps`` is the run's total budget. Without ``--run-dir`` the
run goes on in the checkpoint's run folder (the folder holding it, or the one above
its ``checkpoints/``, when that folder has the run's ``config.json``); a checkpoint
that is in no run folder (e.g. a shipped ``agents/models/*.zip``) starts the fresh
default run folder instead: its own folder is never turned into a run. A folder that
already holds another run is refused unless ``--overwrite`` (:mod:`agents.artifacts.run_folder`).
A resume continues the run as its ``config.json`` records it: every option that shapes
the run (``--env``, ``--algo``, ``--n-trailers``, ``--randomize``, ``--seed``,
``--n-envs``, ``--shaping``, the hyperparameter file's entry, the training options)
must be the run's (the refusal names the option, the run's value and the one given);
``--timesteps`` must be above the checkpoint's steps; the files the run reads back (its
record, ``evaluations.csv``, the best model's card) are checked before anything is
written. The rows of ``evaluations.csv`` up to the checkpoint stay as they were written;
later ones (an abandoned continuation) go.

The training options are records (:mod:`agents.algorithms.options`, each documented
there; ``--help`` lists their flags): ``--init-from MODEL`` fine-tunes a new run from MODEL's
policy (an imitation agent, another run's best model), its observation statistics
restored and frozen, ``--critic-warmup STEPS`` training the value function alone first;
``--start-curriculum FROM,STEPS`` grows the training starts to the scene's own;
``--start-replay SHARE`` begins a share of the episodes from starts that failed before
(the evaluations, and so the learning curve and the kept model, use the scene's starts).

``--stop-on-plateau WINDOW,EPS`` ends the run early once its validation headline rate
(safe for Reverse, success otherwise) is flat: its last WINDOW evaluations within EPS
of their mean (:mod:`agents.evaluation.learning_curves`), once that level is more than
EPS from the first evaluation's (a run that has not started learning goes on) and the
end of the curve no longer rises by the trend test that the curve tables apply (the
line through the last third of the steps); the cards record the step
(``stopped_on_plateau_at``).

``--export PATH`` copies the best model, its card, statistics and learning curve to
PATH (e.g. ``agents/models/``); existing files there are refused unless ``--overwrite``
(:func:`agents.artifacts.run_folder.export_model`). ``--export-model final`` makes the
model at the end of the budget the run's result (what ``--export`` copies and
``agents.reproduce`` names): for a fine-tuning run whose validation rate stays within an
episode or two of its start, where the best by validation is a coin toss.

Nothing is unpickled from ``--resume``'s files unless ``--trust-pickle``
(:mod:`agents.artifacts`): observation statistics are JSON, the model's pickled
entries are rebuilt from the environment and the hyperparameter file, and a SAC/TD3
replay buffer (SB3 saves it as a pickle) is refused without the flag.

``--backend rllib`` trains PPO on Ray RLlib instead (:mod:`agents.training.rllib`):
``--num-env-runners K`` remote runners, each stepping one native batch of
``--n-envs`` convoys, on a local Ray or the cluster at ``--address``.

Everything is checked before anything is built or written (exit status 2 naming the
argument): the hyperparameter file (:mod:`agents.training.config`), ``--resume``'s
files, ``--export``'s target (writable, no link, no file there without
``--overwrite``), the run folder (no link among its run files; ``<run>/.lock`` held by
a live run refuses a second writer) and the bounds of :mod:`agents.artifacts.limits`:
``--n-envs`` <= 65,536, ``--timesteps`` <= 2**31, ``--eval-episodes`` <= 100,000,
``--torch-threads`` <= 4 per CPU, ``--seed`` + steps < 2**32, ``--num-env-runners``
<= the cluster's CPUs, ``--address`` of the form ``auto``, ``HOST:PORT`` or
``ray://HOST:PORT``.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

from agents.algorithms.options import TRAINING_OPTIONS, OptionError, TrainingOption
from agents.algorithms.options.base import Flag
from agents.artifacts import limits
from agents.artifacts.run_folder import (
    EXPORTABLE_MODELS,
    RLLIB_CHECKPOINT,
    RunFolderError,
    claimed_run_dir,
    default_run_dir,
    export_model,
    run_dir_of_checkpoint,
)
from agents.artifacts.sb3_zip import ALGOS
from agents.commands import options as cli
from agents.commands.sources import SourceModel, resumed_run_problem, target_problem
from agents.envs import settings_by_count
from agents.policies.sb3 import limit_torch_threads
from agents.progress import plural
from agents.training.config import Hyperparams, TrainConfig, load_hyperparams
from agents.training.sb3 import train

#: How the command line reads each kind of a training option's value.
_VALUE_TYPES: dict[str, Callable[[str], object]] = {
    "share": cli.open_share,
    "schedule": cli.start_curriculum,
    "path": Path,
    "text": str,
}


def _optional_positive(parser: argparse.ArgumentParser, flag: str, help: str) -> None:
    """An optional count >= 1 whose default (None) is worked out from the other settings."""
    parser.add_argument(flag, type=cli.bounded(1, limits.MAX_TIMESTEPS), default=None, help=help)


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.train"),
        description="Train PPO, PPO-Lagrangian, SAC or TD3 on a trailer_env scene "
        "(native batched env).",
    )
    _add_run_arguments(parser)
    _add_rllib_arguments(parser)
    _add_folder_arguments(parser)
    for option in TRAINING_OPTIONS:
        for flag in option.FLAGS:
            _add_flag(parser, flag)
    _add_schedule_arguments(parser)
    return parser


def _add_flag(parser: argparse.ArgumentParser, flag: Flag) -> None:
    """A training option's flag (:class:`agents.algorithms.options.base.Flag`)."""
    kind = cli.bounded(flag.low, flag.high) if flag.kind == "count" else _VALUE_TYPES[flag.kind]
    parser.add_argument(
        flag.name, type=kind, default=flag.default, metavar=flag.metavar, help=flag.help
    )


def _add_run_arguments(parser: argparse.ArgumentParser) -> None:
    """What to train: backend, scene, algorithm, n, physics, budget, seed, batch, file."""
    parser.add_argument(
        "--backend",
        choices=("sb3", "rllib"),
        default="sb3",
        help="sb3: stable-baselines3 on this machine (default); rllib: Ray RLlib PPO, "
        "local Ray or a cluster (--address), see agents.training.rllib",
    )
    cli.add_env(parser)
    parser.add_argument(
        "--algo",
        required=True,
        choices=sorted(ALGOS),
        help="algorithm: " + "; ".join(f"{name}: {record.label}" for name, record in ALGOS.items()),
    )
    cli.add_n_trailers(parser, ranges=True)
    cli.add_randomize(
        parser, "randomised physics, a preset over the file's env_kwargs (trailer_env.randomize)"
    )
    _optional_positive(
        parser,
        "--timesteps",
        "total training budget in environment steps "
        "(default: n_timesteps of the hyperparameter file)",
    )
    cli.add_seed(parser, 0, "random seed (default 0)")
    parser.add_argument(
        "--n-envs",
        type=cli.bounded(1, limits.MAX_N_ENVS),
        default=None,
        help="environments per batch (default: from the hyperparameters), at most "
        f"{limits.MAX_N_ENVS:,}; with --backend rllib: per env runner",
    )
    parser.add_argument(
        "--hyperparams",
        type=Path,
        default=None,
        help="folder of <algo>.yml files (default agents/hyperparams)",
    )


def _add_rllib_arguments(parser: argparse.ArgumentParser) -> None:
    """The RLlib backend's runners and cluster."""
    parser.add_argument(
        "--num-env-runners",
        type=cli.non_negative_int,
        default=1,
        help="rllib: remote env runners, each stepping one native batch (default 1); at "
        "most the CPUs of the machine (local Ray) or of the cluster (--address)",
    )
    parser.add_argument(
        "--address",
        default=None,
        help="rllib: address of a running Ray cluster (ray start --head prints it; "
        "'auto' finds a local one); default: start a local Ray",
    )


def _add_folder_arguments(parser: argparse.ArgumentParser) -> None:
    """Where the run goes, what it continues, what it may replace and unpickle."""
    parser.add_argument(
        "--run-dir",
        type=Path,
        default=None,
        help="run folder (default runs/<scene>_n<n>_<algo>_s<seed>; when resuming, the "
        "checkpoint's run folder if it is in one)",
    )
    parser.add_argument(
        "--resume", type=Path, default=None, help="checkpoint (.zip) to continue from"
    )
    cli.add_overwrite(
        parser, "start afresh in a run folder that already holds a run; replace --export's files"
    )
    cli.add_trust_pickle(
        parser,
        "parts of --resume's files (SB3 serialized entries, SAC/TD3 replay buffers, "
        "legacy .pkl statistics)",
    )
    parser.add_argument(
        "--export", type=Path, default=None, help="copy the best model (+ card, curve) to this .zip"
    )
    parser.add_argument(
        "--export-model",
        choices=sorted(EXPORTABLE_MODELS),
        default=None,
        help="the run's result, which --export copies and agents.reproduce names: the best "
        "by validation (default) or the final model",
    )


def _add_schedule_arguments(parser: argparse.ArgumentParser) -> None:
    """Evaluations, checkpoints, the plateau stop, threads and output."""
    _optional_positive(parser, "--eval-freq", "steps between evaluations (default: budget / 20)")
    cli.add_episodes(parser, 50, "episodes per evaluation (default 50)", flag="--eval-episodes")
    _optional_positive(
        parser, "--checkpoint-freq", "steps between checkpoints (default: budget / 5)"
    )
    parser.add_argument(
        "--stop-on-plateau",
        type=cli.plateau_rule,
        default=None,
        metavar="WINDOW,EPS",
        help="stop once the validation headline rate is flat: its last WINDOW evaluations "
        "within EPS of their mean, and its last third no longer rising (e.g. 5,0.05; sb3 only)",
    )
    cli.add_torch_threads(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--quiet", action="store_true", help="no evaluation lines")


def _sources(args: argparse.Namespace) -> list[SourceModel]:
    """The models the run starts from: ``--resume``'s checkpoint, ``--init-from``'s model."""
    given = (("--resume", args.resume, True), ("--init-from", args.init_from, False))
    return [SourceModel(flag, path, resumed) for flag, path, resumed in given if path is not None]


def _training_options(
    parser: argparse.ArgumentParser, args: argparse.Namespace
) -> tuple[TrainingOption, ...]:
    """The training options the command line gives, each checked against the command's
    scene, algorithm and backend (before any file is read)."""
    options = []
    for kind in TRAINING_OPTIONS:
        try:
            option = kind.from_args(args)
            if option is not None:
                option.check_command(args.env, args.algo, args.backend)
                options.append(option)
        except OptionError as error:
            parser.error(f"argument {error.flag}: {error}")
    return tuple(options)


def _check_backend(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse the options the chosen backend does not have (the training options refuse
    it themselves, :meth:`~agents.algorithms.options.base.TrainingOption.check`)."""
    if args.backend != "rllib":
        if args.address is not None:
            parser.error("argument --address: only with --backend rllib")
        return
    for name, unsupported in (
        ("--resume", args.resume is not None),
        ("--export", args.export is not None),
        ("--export-model", args.export_model is not None),
        ("--stop-on-plateau", args.stop_on_plateau is not None),
        *(
            (kind.flag(), kind.given(args))
            for kind in TRAINING_OPTIONS
            if "rllib" not in kind.BACKENDS
        ),
    ):
        if unsupported:
            parser.error(f"argument {name}: not supported with --backend rllib")
    from agents.training.rllib import RLLIB_ALGOS, address_problem, local_cpus

    if args.algo not in RLLIB_ALGOS:
        trained = ", ".join(RLLIB_ALGOS)
        parser.error(f"argument --algo: --backend rllib trains {trained}, not {args.algo}")
    if args.address is not None:
        problem = address_problem(args.address)
        if problem is not None:
            parser.error(f"argument --address: {problem}")
    elif args.num_env_runners > local_cpus():
        parser.error(
            f"argument --num-env-runners: {args.num_env_runners} runners, but this "
            f"machine has {local_cpus()} CPUs (one runner per CPU)"
        )


def _hyperparams(parser: argparse.ArgumentParser, args: argparse.Namespace) -> Hyperparams:
    """The hyperparameter file's entry; ``--shaping`` (``none`` included) replaces its
    ``shaping``."""
    try:
        hp = (
            load_hyperparams(args.algo, args.env, args.hyperparams)
            if args.hyperparams is not None
            else load_hyperparams(args.algo, args.env)
        )
    except (FileNotFoundError, KeyError, ValueError) as error:
        text = str(error.args[0]) if isinstance(error, KeyError) else str(error)
        parser.error(f"argument --hyperparams: {text}")
    if args.shaping is not None:
        hp.shaping = None
    return hp


def config_from_args(
    parser: argparse.ArgumentParser, args: argparse.Namespace, command: list[str]
) -> TrainConfig:
    """The run's :class:`TrainConfig` from the command line and the hyperparameter file.

    With ``--backend rllib`` ``--n-envs`` counts the convoys of one env runner; the
    configuration records all runners' together.
    """
    options = _training_options(parser, args)
    hp = _hyperparams(parser, args)
    n_envs = args.n_envs
    if args.backend == "rllib":
        runners = max(args.num_env_runners, 1)
        n_envs = (n_envs or max(hp.n_envs // runners, 1)) * runners
    try:
        config = TrainConfig.resolve(
            args.env,
            args.algo,
            args.n_trailers,
            args.seed,
            hp,
            timesteps=args.timesteps,
            n_envs=n_envs,
            backend=args.backend,
            command=command,
            randomize=args.randomize,
            options=options,
        )
    except OptionError as error:
        parser.error(f"argument {error.flag}: {error}")
    except ValueError as error:
        parser.error(f"argument --timesteps, --n-envs or --seed (or the file's): {error}")
    try:
        settings_by_count(config.env_kwargs)
    except (TypeError, ValueError) as error:
        parser.error(f"argument --n-trailers, --randomize (or the file's env_kwargs): {error}")
    return config


def _check_sources(
    parser: argparse.ArgumentParser, args: argparse.Namespace, config: TrainConfig
) -> None:
    """Refuse a --resume or --init-from model that does not load in the run's env (the
    file's env_kwargs, such as observe_params, change what it observes), and a --resume
    whose checkpoint is already at the run's budget."""
    for source in _sources(args):
        problem, steps = source.load_problem(
            args.algo, args.env, config.env_kwargs, args.trust_pickle
        )
        if problem is not None:
            parser.error(f"argument {source.flag}: {problem}")
        if source.resumed and config.budget <= steps:
            # It would train nothing and record a smaller budget than the run had.
            parser.error(
                f"argument --timesteps: {args.resume} is at {steps:,} steps; the run's total "
                f"budget must be above that, got {config.budget:,}"
            )


def _refuse(parser: argparse.ArgumentParser, problem: tuple[str, str] | None) -> None:
    """Exit with status 2 on a problem (the flag to name, what is wrong)."""
    if problem is not None:
        parser.error(f"argument {problem[0]}: {problem[1]}")


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2, with a message)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    _check_backend(parser, args)
    command = ["python", "-m", "agents.train", *(sys.argv[1:] if argv is None else argv)]
    config = config_from_args(parser, args, command)
    hp = config.hyperparams
    normalizes = hp.normalize is not None and bool(hp.normalize.get("norm_obs", True))
    for source in _sources(args):
        problem = source.file_problem(args.algo) or source.statistics_problem(normalizes)
        if problem is not None:
            parser.error(f"argument {source.flag}: {problem}")
    # A --resume must continue its run as recorded, checked before its files are loaded.
    _refuse(parser, None if args.resume is None else resumed_run_problem(args.resume, config))
    _check_sources(parser, args, config)
    default = default_run_dir(args.env, args.algo, args.n_trailers, args.seed)
    own_run = None if args.resume is None else run_dir_of_checkpoint(args.resume)
    target = args.run_dir or own_run or default
    _refuse(
        parser, target_problem(target, args.resume, args.init_from, args.export, args.overwrite)
    )
    try:
        with claimed_run_dir(default, args.run_dir, args.resume, args.overwrite) as run_dir:
            return _run(parser, args, config, run_dir)
    except RunFolderError as error:
        parser.error(f"argument --run-dir: {error}")


def _run(
    parser: argparse.ArgumentParser, args: argparse.Namespace, config: TrainConfig, run_dir: Path
) -> int:
    """Train into the (locked) run folder."""
    limit_torch_threads(args.torch_threads)
    started = time.perf_counter()
    if args.backend == "rllib":
        return _run_rllib(parser, args, config, run_dir, started)
    model = train(
        config,
        run_dir,
        resume=args.resume,
        eval_freq=args.eval_freq,
        eval_episodes=args.eval_episodes,
        checkpoint_freq=args.checkpoint_freq,
        progress_bar=not args.no_progress,
        verbose=0 if args.quiet else 1,
        trust_pickle=args.trust_pickle,
        stop_on_plateau=args.stop_on_plateau,
    )
    print(
        f"trained {args.algo} on {args.env} (n = {args.n_trailers}) to {model.num_timesteps} "
        f"steps in {time.perf_counter() - started:.0f} s; run folder {run_dir}"
    )
    if args.export is not None:
        exported = export_model(
            run_dir, args.export, overwrite=args.overwrite, model=args.export_model or "best"
        )
        print(f"exported {exported}")
    return 0


def _run_rllib(
    parser: argparse.ArgumentParser,
    args: argparse.Namespace,
    config: TrainConfig,
    run_dir: Path,
    started: float,
) -> int:
    """Train with RLlib into the (locked) run folder."""
    from agents.training.rllib import ClusterTooSmallError, train_rllib

    try:
        totals = train_rllib(
            config,
            run_dir,
            num_env_runners=args.num_env_runners,
            address=args.address,
            verbose=0 if args.quiet else 1,
        )
    except ConnectionError as error:
        parser.error(f"argument --address: {error}")
    except ClusterTooSmallError as error:
        parser.error(f"argument --num-env-runners: {error}")
    print(
        f"trained ppo on {args.env} (n = {args.n_trailers}) with RLlib to "
        f"{plural(totals.timesteps, 'step')} in {time.perf_counter() - started:.0f} s "
        f"({totals.env_steps_per_s:.0f} env steps/s, "
        f"{plural(args.num_env_runners, 'runner')}); "
        f"checkpoint {run_dir / RLLIB_CHECKPOINT}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
