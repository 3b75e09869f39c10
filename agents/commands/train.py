"""Train a stable-baselines3 agent on a trailer_env scene through the native batched env.

Usage::

    python -m agents.train --env trailer_env/Reverse-v0 --algo ppo --n-trailers 2 \
        --timesteps 1000000 --seed 0

Hyperparameters come from ``agents/hyperparams/<algo>.yml`` (rl-zoo3 format). The
run folder (default ``runs/<scene>_n<n>_<algo>_s<seed>``) receives:

* ``config.json``: the run's record (:class:`agents.training.config.TrainConfig`: the command's
  arguments and the hyperparameters used), also the base of every model card;
* ``evaluations.csv``: the learning curve (periodic seeded safety evaluations);
* ``best_model.zip`` (+ card ``best_model.json``), ``final_model.zip`` (+ card), each
  with ``*_vecnormalize.json`` (statistics, JSON) when the hyperparameters normalise
  observations;
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
``--n-envs``, ``--shaping``, the hyperparameter file's entry, ``--init-from``,
``--critic-warmup``, the start options) must be the run's, or the refusal names the
option with the run's value and the one given; ``--timesteps`` must be above the
checkpoint's steps; and the files the run reads back (its record, ``evaluations.csv``,
the best model's card) are checked before anything is written. The rows of
``evaluations.csv`` up to the checkpoint stay as they were written; later ones (an
abandoned continuation) go.

``--init-from MODEL`` fine-tunes: a new run whose policy starts as MODEL's (an imitation
agent, another run's best model) under this run's hyperparameters, MODEL's observation
statistics restored and frozen (the policy reads its inputs through them). ``--critic-warmup
STEPS`` first trains the value function alone, so that PPO's first updates follow advantages
of a critic that knows the policy (:class:`agents.training.callbacks.CriticWarmup`). A
fine-tuning run is resumed with ``--resume`` and the same ``--init-from``.

``--start-curriculum FROM,STEPS`` grows the training starts' perturbation from FROM times
the scene's size to its own over the first STEPS steps (Reverse-v1, whose start is a
perturbation of one size; :class:`agents.training.callbacks.StartCurriculum`); the
evaluations, and so the learning curve and the kept model, use the scene's starts.

``--stop-on-plateau WINDOW,EPS`` ends the run early once its validation headline rate
(safe for Reverse, success otherwise) is flat: its last WINDOW evaluations within EPS
of their mean (:mod:`agents.evaluation.learning_curves`), once that level is more than
EPS from the first evaluation's (a run that has not started learning goes on) and the
end of the curve no longer rises by the trend test that the curve tables apply (the
line through the last third of the steps); the cards record the step
(``stopped_on_plateau_at``).

``--export PATH`` copies the best model, its card, statistics and learning curve to
PATH (e.g. ``agents/models/``); existing files there are refused unless ``--overwrite``
(:func:`agents.artifacts.run_folder.export_model`).

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
import json
import sys
import time
from pathlib import Path

from agents.algorithms import algorithm
from agents.artifacts import limits
from agents.artifacts.cards import read_card, trained_with_mirror
from agents.artifacts.paths import pickled_stats_path, replay_buffer_path, stats_path
from agents.artifacts.run_folder import (
    CONFIG_FILE,
    RLLIB_CHECKPOINT,
    RunFolderError,
    checkpoint_folder,
    claimed_run_dir,
    default_run_dir,
    export_model,
    export_problem,
    holds_run,
    read_record,
    record_differences,
    resume_problem,
    run_dir_of_checkpoint,
    symlink_problem,
)
from agents.artifacts.sb3_zip import ALGOS, UnsafeFileError
from agents.artifacts.stats import read_stats
from agents.commands import options as cli
from agents.envs import settings_by_count
from agents.policies.sb3 import detect_algo, limit_torch_threads, load_model
from agents.progress import plural
from agents.training.config import TrainConfig, load_hyperparams, shaping_setting
from agents.training.sb3 import train
from trailer_env.json_types import JSONObject
from trailer_env.registry import core_class_of


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
    parser.add_argument(
        "--hyperparams",
        type=Path,
        default=None,
        help="folder of <algo>.yml files (default agents/hyperparams)",
    )
    parser.add_argument(
        "--shaping",
        default=None,
        metavar="POTENTIAL",
        help="potential-based reward shaping over the file's `shaping` (sb3 only): "
        "'lqr' (the log of the LQR's cost-to-go, trailer_env.shaping) or 'none'; the "
        "success metric and the recorded returns stay the scene's",
    )
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
    parser.add_argument(
        "--init-from",
        type=Path,
        default=None,
        metavar="MODEL",
        help="fine-tune: start a new run from this model's policy (e.g. an imitation "
        "agent), its observation statistics frozen; with --resume, the run's own",
    )
    parser.add_argument(
        "--critic-warmup",
        type=cli.bounded(0, limits.MAX_TIMESTEPS),
        default=0,
        metavar="STEPS",
        help="with --init-from (ppo, ppo_lag): train the value function alone for this "
        "many steps before the policy moves (default 0)",
    )
    parser.add_argument(
        "--start-curriculum",
        type=cli.start_curriculum,
        default=None,
        metavar="FROM,STEPS",
        help="grow the training starts' perturbation linearly from FROM (in (0, 1)) times "
        "the scene's size to its own over the first STEPS steps (Reverse-v1; sb3 only); "
        "evaluations use the scene's starts",
    )
    parser.add_argument(
        "--start-replay",
        type=cli.open_share,
        default=None,
        metavar="SHARE",
        help="begin this share (in (0, 1)) of the training episodes from starts whose "
        "episodes failed before (trailer_env.start_replay; sb3, one count of trailers, no "
        "--randomize); evaluations use the scene's starts",
    )
    parser.add_argument(
        "--start-replay-max",
        type=cli.bounded(1, 2**31),
        default=None,
        metavar="K",
        help="with --start-replay: a start leaves the buffer once K of its replays failed "
        "(default: it returns after every failure)",
    )
    cli.add_overwrite(
        parser, "start afresh in a run folder that already holds a run; replace --export's files"
    )
    cli.add_trust_pickle(
        parser,
        "parts of --resume's files (SB3 serialized entries, SAC/TD3 replay buffers, "
        "legacy .pkl statistics)",
    )
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
    parser.add_argument(
        "--export", type=Path, default=None, help="copy the best model (+ card, curve) to this .zip"
    )
    cli.add_torch_threads(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--quiet", action="store_true", help="no evaluation lines")
    return parser


def _check_resume_file(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse a --resume that is missing or of another algorithm (before anything else)."""
    if not args.resume.is_file():
        parser.error(f"argument --resume: no checkpoint file {args.resume}")
    try:
        saved_algo = detect_algo(args.resume)
    except ValueError as error:
        parser.error(f"argument --resume: {error}")
    if saved_algo != args.algo:
        parser.error(f"argument --resume: {args.resume} was saved by {saved_algo}, not {args.algo}")


def _check_resume(
    parser: argparse.ArgumentParser, args: argparse.Namespace, env_kwargs: JSONObject
) -> int:
    """Refuse a --resume that is damaged, unsafe to load or made for other observations than
    the run's env (``env_kwargs``: the file's, with the command's n and physics), after
    :func:`_check_resume_file`; returns its step count."""
    try:
        model = load_model(
            args.resume,
            args.algo,
            env_id=args.env,
            env_kwargs=env_kwargs,
            trust_pickle=args.trust_pickle,
        )
        if stats_path(args.resume).is_file():
            read_stats(stats_path(args.resume))
        elif pickled_stats_path(args.resume) is not None and not args.trust_pickle:
            raise UnsafeFileError(
                f"its statistics {pickled_stats_path(args.resume)} are a pickle; "
                "pass --trust-pickle to load them"
            )
        buffer = replay_buffer_path(args.resume)
        if buffer is not None and not args.trust_pickle:
            raise UnsafeFileError(
                f"its replay buffer {buffer} is a pickle; pass --trust-pickle to load it "
                "(only if you trust the file)"
            )
    except (ValueError, FileNotFoundError) as error:
        parser.error(f"argument --resume: {error}")
    return int(model.num_timesteps)


def _start_flags(key: str, value: object) -> str:
    """The flags that give a run's recorded start setting (``start_curriculum`` or
    ``start_replay`` of ``config.json``), for a refusal message."""
    if not isinstance(value, dict):
        return f"no --{key.replace('_', '-')}"
    if key == "start_curriculum":
        return f"--start-curriculum {value.get('from')},{value.get('steps')}"
    flags = f"--start-replay {value.get('fraction')}"
    if "max_replays" in value:
        flags += f" --start-replay-max {value['max_replays']}"
    return flags


#: Keys of a training run's record that its continuation may change: the command, the
#: total budget (which only grows) and the totals of the run so far.
RESUMABLE_KEYS = ("command", "budget", "timesteps", "wall_time_s", "stopped_on_plateau_at")
#: Keys of the record checked apart, with messages that give the flags to repeat.
_STARTS = ("start_curriculum", "start_replay")
_FINE_TUNING = ("init_from", "critic_warmup")
#: The option that sets a key of the record (the hyperparameter file sets the others).
_FLAGS = {
    "algo": "--algo",
    "env_id": "--env",
    "seed": "--seed",
    "n_envs": "--n-envs",
    "shaping": "--shaping",
    "env_kwargs.n_trailers": "--n-trailers",
    "env_kwargs.randomize": "--randomize",
}


def _shown(value: object) -> str:
    """A record's value in a refusal message."""
    if value is None:
        return "none"
    return value if isinstance(value, str) else json.dumps(value, sort_keys=True)


def _check_budget(
    parser: argparse.ArgumentParser, args: argparse.Namespace, config: TrainConfig, steps: int
) -> None:
    """Refuse a --resume whose total budget is not above the checkpoint's ``steps``: it
    would train nothing and record a smaller budget than the run had."""
    if config.budget <= steps:
        parser.error(
            f"argument --timesteps: {args.resume} is at {steps:,} steps; the run's total "
            f"budget must be above that, got {config.budget:,}"
        )


def _check_resumed_run(
    parser: argparse.ArgumentParser, args: argparse.Namespace, config: TrainConfig
) -> None:
    """Refuse a --resume that does not continue the checkpoint's run as it was recorded
    (before its files are loaded): every setting that shapes the run (scene, algorithm,
    n, physics, seed, batch, shaping, the hyperparameter file's entry) must be the run's;
    so must its --init-from and --critic-warmup (the frozen statistics and the warm-up
    depend on them) and its --start-curriculum and --start-replay (the schedule and the
    buffer's rules go on). The message names the option, with the run's value and the
    one given. A run folder whose record is damaged, or that holds another trainer's run,
    is refused likewise."""
    own_run = run_dir_of_checkpoint(args.resume)
    if own_run is None:
        folder = checkpoint_folder(args.resume)
        if holds_run(folder):  # its learning curve without its record: a damaged run
            parser.error(f"argument --resume: {folder / CONFIG_FILE} is missing")
        return
    problem = symlink_problem(own_run)  # the folder the run goes on in, first
    if problem is not None:
        parser.error(f"argument --run-dir: {problem}")
    try:
        saved = read_record(own_run)
    except ValueError as error:
        parser.error(f"argument --resume: {error}")
    if saved.get("recipe") is not None:  # e.g. an imitation run: another trainer's record
        parser.error(
            f"argument --resume: {own_run} holds a {saved['recipe']} run, not one of "
            "agents.train; fine-tune its model with --init-from"
        )
    wanted = config.document()
    for key in _STARTS:
        if saved.get(key) != wanted.get(key):
            parser.error(
                f"argument --resume: {own_run} was trained with "
                f"{_start_flags(key, saved.get(key))}; resume it with the same"
            )
    saved_from, saved_warmup = saved.get("init_from"), saved.get("critic_warmup", 0)
    same_source = (saved_from is None) == (args.init_from is None) and (
        saved_from is None or Path(str(saved_from)).resolve() == args.init_from.resolve()
    )
    if not same_source or saved_warmup != args.critic_warmup:
        parser.error(
            f"argument --resume: {own_run} was trained with --init-from {saved_from} "
            f"--critic-warmup {saved_warmup}; resume it with the same"
        )
    free = (*RESUMABLE_KEYS, *_STARTS, *_FINE_TUNING)
    for key, old, new in record_differences(saved, wanted, free):
        flag = _FLAGS.get(key) or _FLAGS.get(key.partition(".")[0]) or "--hyperparams"
        parser.error(
            f"argument {flag}: {own_run} was trained with {key} = {_shown(old)}, not "
            f"{_shown(new)}; resume it with the same"
        )


def _check_init_from(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse an --init-from that is missing, of another algorithm or trained with the
    mirror, and a --critic-warmup without it or for an algorithm without a separate value
    function (before anything else)."""
    if args.critic_warmup and args.init_from is None:
        parser.error("argument --critic-warmup: only with --init-from")
    if args.critic_warmup and algorithm(args.algo).off_policy:
        parser.error(f"argument --critic-warmup: {args.algo} has no separate value function")
    if args.init_from is None:
        return
    if algorithm(args.algo).off_policy:
        # Only the policy's weights would carry over: the replay buffer and SAC's entropy
        # coefficient would restart, and learning_starts steps would act at random.
        parser.error(
            f"argument --init-from: {args.algo} is off-policy; only on-policy runs fine-tune"
        )
    if not args.init_from.is_file():
        parser.error(f"argument --init-from: no model file {args.init_from}")
    try:
        saved_algo = detect_algo(args.init_from)
        if saved_algo != args.algo:
            raise ValueError(f"{args.init_from} was saved by {saved_algo}, not {args.algo}")
        if trained_with_mirror(read_card(args.init_from)):
            # It acts as the mean of its network and the network's mirror image; training
            # the bare network would start from other decisions than the model's.
            raise ValueError(f"{args.init_from} was trained with the mirror (imitation.mirror)")
    except (ValueError, FileNotFoundError) as error:
        parser.error(f"argument --init-from: {error}")


def _check_init_from_model(
    parser: argparse.ArgumentParser, args: argparse.Namespace, env_kwargs: JSONObject
) -> None:
    """Refuse an --init-from that does not load in the run's env (``env_kwargs``: the
    file's, with the command's n and physics) or whose statistics are damaged."""
    if args.init_from is None:
        return
    try:
        load_model(
            args.init_from,
            args.algo,
            env_id=args.env,
            env_kwargs=env_kwargs,
            trust_pickle=args.trust_pickle,
        )
        if stats_path(args.init_from).is_file():
            read_stats(stats_path(args.init_from))
    except (ValueError, FileNotFoundError) as error:
        parser.error(f"argument --init-from: {error}")


def _check_start_curriculum(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse a --start-curriculum on a scene whose starts have no size to scale."""
    if args.start_curriculum is not None and not core_class_of(args.env).start_scalable:
        parser.error(
            f"argument --start-curriculum: {args.env}'s starts have no perturbation size to "
            "scale (Reverse-v1's have)"
        )


def _check_backend(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse the options the chosen backend does not have."""
    if args.backend == "rllib":
        for name, unsupported in (
            ("--resume", args.resume is not None),
            ("--export", args.export is not None),
            ("--stop-on-plateau", args.stop_on_plateau is not None),
            ("--shaping", args.shaping not in (None, "none")),
            ("--init-from", args.init_from is not None),
            ("--start-curriculum", args.start_curriculum is not None),
            ("--start-replay", args.start_replay is not None),
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
    elif args.address is not None:
        parser.error("argument --address: only with --backend rllib")


def config_from_args(
    parser: argparse.ArgumentParser, args: argparse.Namespace, command: list[str]
) -> TrainConfig:
    """The run's :class:`TrainConfig` from the command line and the hyperparameter file.

    With ``--backend rllib`` ``--n-envs`` counts the convoys of one env runner; the
    configuration records all runners' together.
    """
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
        try:
            hp.shaping = shaping_setting(args.shaping, "--shaping")
        except ValueError as error:
            parser.error(f"argument {error}")
    if hp.shaping is not None and isinstance(args.n_trailers, tuple):
        # The potential is one LQR's cost-to-go, designed for one n.
        parser.error(
            "argument --shaping (or the file's shaping): one count of trailers, not a range"
        )
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
            init_from=None if args.init_from is None else str(args.init_from),
            critic_warmup=args.critic_warmup,
            randomize=args.randomize,
            start_curriculum=args.start_curriculum,
            start_replay=args.start_replay,
            start_replay_max=args.start_replay_max,
        )
    except ValueError as error:
        flags = "--timesteps, --n-envs or --seed (or the file's)"
        if "critic_warmup" in str(error):
            flags = "--critic-warmup"
        elif "start_replay_max" in str(error):
            flags = "--start-replay-max"
        elif "start_replay" in str(error):
            flags = "--start-replay"
        parser.error(f"argument {flags}: {error}")
    try:
        settings_by_count(config.env_kwargs)
    except (TypeError, ValueError) as error:
        parser.error(f"argument --n-trailers, --randomize (or the file's env_kwargs): {error}")
    if (
        args.init_from is not None
        and hp.normalize is not None
        and hp.normalize.get("norm_obs", True)
        and not stats_path(args.init_from).is_file()
    ):
        parser.error(
            f"argument --init-from: {args.init_from} has no observation statistics "
            f"({stats_path(args.init_from).name}), but the hyperparameters normalise observations"
        )
    if (
        args.resume is not None
        and hp.normalize is not None
        and hp.normalize.get("norm_obs", True)
        and not stats_path(args.resume).is_file()
        and pickled_stats_path(args.resume) is None
    ):
        parser.error(
            f"argument --resume: {args.resume} has no observation statistics "
            f"({stats_path(args.resume).name}), but the hyperparameters normalise observations"
        )
    return config


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2, with a message)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    _check_backend(parser, args)
    _check_start_curriculum(parser, args)
    if args.resume is not None:
        _check_resume_file(parser, args)
    _check_init_from(parser, args)
    command = ["python", "-m", "agents.train", *(sys.argv[1:] if argv is None else argv)]
    config = config_from_args(parser, args, command)
    # The saved models load in the run's env: the file's env_kwargs (such as
    # observe_params) change what it observes.
    if args.resume is not None:
        _check_resumed_run(parser, args, config)
        _check_budget(parser, args, config, _check_resume(parser, args, config.env_kwargs))
    _check_init_from_model(parser, args, config.env_kwargs)
    default = default_run_dir(args.env, args.algo, args.n_trailers, args.seed)
    own_run = None if args.resume is None else run_dir_of_checkpoint(args.resume)
    target = args.run_dir or own_run or default
    if args.resume is not None and (target.resolve() == own_run or not holds_run(target)):
        # The files of the folder the run goes on in (a folder holding another run is
        # refused, or cleared with --overwrite): checked before anything is written.
        problem = resume_problem(target)
        if problem is not None:
            parser.error(f"argument --resume: cannot resume into {target}: {problem}")
    if args.init_from is not None and args.init_from.resolve().is_relative_to(target.resolve()):
        # --overwrite would clear it, and the run's own models would replace it.
        parser.error(
            f"argument --init-from: {args.init_from} lies in the run folder {target}; "
            "copy it out or choose another --run-dir"
        )
    if args.export is not None:
        problem = export_problem(args.export, args.overwrite)
        if problem is not None:
            parser.error(f"argument --export: {problem}")
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
        from agents.training.rllib import ClusterTooSmallError, train_rllib

        try:
            record = train_rllib(
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
            f"{plural(record['timesteps'], 'step')} in {time.perf_counter() - started:.0f} s "
            f"({record['env_steps_per_s']:.0f} env steps/s, "
            f"{plural(args.num_env_runners, 'runner')}); "
            f"checkpoint {run_dir / RLLIB_CHECKPOINT}"
        )
        return 0
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
        print(f"exported {export_model(run_dir, args.export, overwrite=args.overwrite)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
