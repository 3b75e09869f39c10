"""Train a stable-baselines3 agent on a trailer_env scene through the native batched env.

Usage::

    python -m agents.train --env trailer_env/Reverse-v0 --algo ppo --n-trailers 2 \\
        --timesteps 1000000 --seed 0

Hyperparameters come from ``agents/hyperparams/<algo>.yml`` (rl-zoo3 format). The
run folder (default ``runs/<scene>_n<n>_<algo>_s<seed>``) receives:

* ``config.json``: the run's record (:class:`agents.config.TrainConfig`: the command's
  arguments and the hyperparameters used), also the base of every model card;
* ``evaluations.csv``: the learning curve (periodic seeded safety evaluations);
* ``best_model.zip`` (+ card ``best_model.json``), ``final_model.zip`` (+ card), each
  with ``*_vecnormalize.json`` (statistics, JSON) when the hyperparameters normalise
  observations;
* ``checkpoints/<algo>_<steps>_steps.zip`` (and the replay buffer for SAC/TD3);
* ``logs/``: SB3's training statistics (CSV; TensorBoard too when installed).

``--resume <checkpoint.zip>`` continues a run: the timestep count goes on from the
checkpoint's and ``--timesteps`` is the run's total budget. Without ``--run-dir`` the
run goes on in the checkpoint's run folder (the folder holding it, or the one above
its ``checkpoints/``, when that folder has the run's ``config.json``); a checkpoint
that is in no run folder (e.g. a shipped ``agents/models/*.zip``) starts the fresh
default run folder instead: its own folder is never turned into a run. A folder that
already holds another run is refused unless ``--overwrite`` (:mod:`agents.run_folder`).

``--export PATH`` copies the best model, its card, statistics and learning curve to
PATH (e.g. ``agents/models/``); existing files there are refused unless ``--overwrite``
(:func:`agents.model_files.export_model`).

Nothing is unpickled from ``--resume``'s files unless ``--trust-pickle``
(:mod:`agents.model_files`): observation statistics are JSON, the model's pickled
entries are rebuilt from the environment and the hyperparameter file, and a SAC/TD3
replay buffer (SB3 saves it as a pickle) is refused without the flag.

``--backend rllib`` trains PPO on Ray RLlib instead (:mod:`agents.rllib_backend`):
``--num-env-runners K`` remote runners, each stepping one native batch of
``--n-envs`` convoys, on a local Ray or the cluster at ``--address``.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from agents import cli
from agents.config import TrainConfig, load_hyperparams
from agents.envs import env_settings, make_sb3_env
from agents.model_files import (
    UnsafeFileError,
    export_files,
    load_pickled_stats,
    load_sb3,
    pickled_stats_path,
    read_card,
    read_stats,
    replay_buffer_path,
    restore_stats,
    save_stats,
    stats_path,
    write_card,
)
from agents.policies import ALGOS, algo_class, detect_algo, limit_torch_threads, load_model
from agents.run_folder import (
    BEST_MODEL,
    CHECKPOINTS,
    FINAL_MODEL,
    RLLIB_CHECKPOINT,
    RunFolderError,
    choose_run_dir,
    default_run_dir,
    export_model,
    write_config,
)


def _optional_positive(parser: argparse.ArgumentParser, flag: str, help: str) -> None:
    """An optional count >= 1 whose default (None) is worked out from the other settings."""
    parser.add_argument(flag, type=cli.positive_int, default=None, help=help)


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog="python -m agents.train",
        description="Train PPO, SAC or TD3 on a trailer_env scene (native batched env).",
    )
    parser.add_argument(
        "--backend",
        choices=("sb3", "rllib"),
        default="sb3",
        help="sb3: stable-baselines3 on this machine (default); rllib: Ray RLlib PPO, "
        "local Ray or a cluster (--address), see agents.rllib_backend",
    )
    cli.add_env(parser)
    parser.add_argument("--algo", required=True, choices=sorted(ALGOS), help="algorithm")
    cli.add_n_trailers(parser)
    _optional_positive(
        parser,
        "--timesteps",
        "total training budget in environment steps "
        "(default: n_timesteps of the hyperparameter file)",
    )
    cli.add_seed(parser, 0, "random seed (default 0)")
    _optional_positive(
        parser,
        "--n-envs",
        "environments per batch (default: from the hyperparameters); "
        "with --backend rllib: per env runner",
    )
    parser.add_argument(
        "--num-env-runners",
        type=cli.non_negative_int,
        default=1,
        help="rllib: remote env runners, each stepping one native batch (default 1)",
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
    _optional_positive(parser, "--eval-freq", "steps between evaluations (default: budget / 20)")
    parser.add_argument(
        "--eval-episodes",
        type=cli.positive_int,
        default=50,
        help="episodes per evaluation (default 50)",
    )
    _optional_positive(
        parser, "--checkpoint-freq", "steps between checkpoints (default: budget / 5)"
    )
    parser.add_argument(
        "--export", type=Path, default=None, help="copy the best model (+ card, curve) to this .zip"
    )
    parser.add_argument(
        "--torch-threads", type=cli.positive_int, default=1, help="torch CPU threads (default 1)"
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--quiet", action="store_true", help="no evaluation lines")
    return parser


def _progress_bar_available() -> bool:
    return all(importlib.util.find_spec(name) is not None for name in ("tqdm", "rich"))


def train(
    config: TrainConfig,
    run_dir: Path,
    *,
    resume: Path | None = None,
    eval_freq: int | None = None,
    eval_episodes: int = 50,
    checkpoint_freq: int | None = None,
    progress_bar: bool = True,
    verbose: int = 1,
    trust_pickle: bool = False,
) -> Any:
    """Train (or resume) an SB3 agent; returns the model. See the module docstring for outputs.

    Args:
        config: What to train (:meth:`agents.config.TrainConfig.resolve`).
        run_dir: Run folder.
        resume: Checkpoint to continue from.
        eval_freq, eval_episodes, checkpoint_freq: Evaluation and checkpoint schedule.
        progress_bar: Show SB3's progress bar (needs tqdm and rich).
        verbose: 1 prints one line per evaluation.
        trust_pickle: Allow unpickling ``resume``'s pickled parts (serialized entries,
            replay buffer, legacy statistics); otherwise they are replaced or refused
            (:mod:`agents.model_files`).

    Raises:
        ValueError: If ``resume`` cannot be loaded safely (or at all).
    """
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.noise import NormalActionNoise
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.callbacks import SafetyEvalCallback, StatsCheckpointCallback

    hp = config.hyperparams
    algo, seed, budget, batch = config.algo, config.seed, config.budget, config.n_envs
    env_kwargs = config.env_kwargs
    settings = env_settings(env_kwargs)  # fail early on bad settings
    run_dir.mkdir(parents=True, exist_ok=True)
    start_steps = 0
    venv = make_sb3_env(config.env_id, batch, env_kwargs, seed=seed)
    if hp.normalize is not None:
        normalize = {"gamma": hp.algo_kwargs.get("gamma", 0.99), **hp.normalize}
        venv = VecNormalize(venv, **normalize)
        if resume is not None:
            _restore_checkpoint_stats(venv, resume, trust_pickle)
    kwargs = dict(hp.algo_kwargs)
    if hp.action_noise_std is not None:
        dim = settings.action_dim
        kwargs["action_noise"] = NormalActionNoise(
            np.zeros(dim), hp.action_noise_std * np.ones(dim)
        )
    if resume is not None:
        model = load_sb3(
            resume,
            algo,
            venv.observation_space,
            venv.action_space,
            env=venv,
            algo_kwargs=kwargs,
            trust_pickle=trust_pickle,
        )
        start_steps = int(model.num_timesteps)
        # Fresh starting states, not a replay of the first session's.
        venv.seed(seed + start_steps)
        model.set_random_seed(seed + start_steps)
        buffer = replay_buffer_path(resume)
        if buffer is not None and hasattr(model, "load_replay_buffer"):
            if not trust_pickle:
                raise UnsafeFileError(
                    f"the replay buffer {buffer} is a pickle; pass --trust-pickle to load it"
                )
            model.load_replay_buffer(buffer)
    else:
        model = algo_class(algo)(hp.policy, venv, seed=seed, device="cpu", verbose=0, **kwargs)
    outputs = ["csv"]
    if importlib.util.find_spec("tensorboard") is not None:
        outputs.append("tensorboard")
    model.set_logger(configure(str(run_dir / "logs" / f"from_{start_steps}"), outputs))
    record = config.document()
    write_config(run_dir, record)
    remaining = budget - start_steps
    if remaining <= 0:
        if verbose:
            print(f"{resume} is already at {start_steps} >= {budget} steps: nothing to train")
        return model
    evaluator = SafetyEvalCallback(
        config.env_id,
        env_kwargs,
        run_dir,
        eval_freq=eval_freq or max(budget // 20, batch),
        episodes=eval_episodes,
        resume_from=start_steps if resume is not None else None,
        verbose=verbose,
    )
    checkpoints = StatsCheckpointCallback(
        save_freq=max((checkpoint_freq or max(budget // 5, batch)) // batch, 1),
        save_path=str(run_dir / CHECKPOINTS),
        name_prefix=algo,
        save_replay_buffer=algo in ("sac", "td3"),
    )
    model.learn(
        total_timesteps=remaining,
        callback=[evaluator, checkpoints],
        reset_num_timesteps=resume is None,
        progress_bar=progress_bar and _progress_bar_available(),
    )
    wall = round(evaluator.wall_seconds, 1)
    record.update({"timesteps": int(model.num_timesteps), "wall_time_s": wall})
    final = run_dir / FINAL_MODEL
    model.save(final)
    stats = model.get_vec_normalize_env()
    if stats is not None:
        save_stats(stats, stats_path(final))
    write_card(final, record)
    best = run_dir / BEST_MODEL
    if best.is_file():
        write_card(best, {**record, **read_card(best)})
    return model


def _restore_checkpoint_stats(venv: Any, checkpoint: Path, trust_pickle: bool) -> None:
    """Put ``checkpoint``'s observation statistics into the (training) ``VecNormalize``.

    Raises:
        UnsafeFileError: If they exist only as a pickle and ``trust_pickle`` is false.
    """
    saved = stats_path(checkpoint)
    if saved.is_file():
        restore_stats(venv, read_stats(saved))
        return
    pickled = pickled_stats_path(checkpoint)
    if pickled is None:
        return
    if not trust_pickle:
        raise UnsafeFileError(
            f"the statistics {pickled} are a pickle; pass --trust-pickle to load them"
        )
    loaded = load_pickled_stats(pickled)
    for key in ("obs_rms", "ret_rms", "clip_obs", "clip_reward", "epsilon"):
        setattr(venv, key, getattr(loaded, key))


def _check_resume(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse a --resume that is missing, of another algorithm, damaged or unsafe to load."""
    if not args.resume.is_file():
        parser.error(f"argument --resume: no checkpoint file {args.resume}")
    try:
        saved_algo = detect_algo(args.resume)
    except ValueError as error:
        parser.error(f"argument --resume: {error}")
    if saved_algo != args.algo:
        parser.error(f"argument --resume: {args.resume} was saved by {saved_algo}, not {args.algo}")
    env_kwargs = {"n_trailers": args.n_trailers}
    try:
        load_model(
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


def _check_backend(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse the options the chosen backend does not have."""
    if args.backend == "rllib":
        for name, unsupported in (
            ("--resume", args.resume is not None),
            ("--export", args.export is not None),
        ):
            if unsupported:
                parser.error(f"argument {name}: not supported with --backend rllib")
        if args.algo != "ppo":
            parser.error(f"argument --algo: --backend rllib trains ppo, not {args.algo}")
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
        parser.error(f"argument --hyperparams: {str(error).strip(chr(34) + chr(39))}")
    n_envs = args.n_envs
    if args.backend == "rllib":
        runners = max(args.num_env_runners, 1)
        n_envs = (n_envs or max(hp.n_envs // runners, 1)) * runners
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
    )
    try:
        env_settings(config.env_kwargs)
    except (TypeError, ValueError) as error:
        parser.error(f"argument --n-trailers (or the file's env_kwargs): {error}")
    return config


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2, with a message)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    _check_backend(parser, args)
    if args.resume is not None:
        _check_resume(parser, args)
    command = ["python", "-m", "agents.train", *(sys.argv[1:] if argv is None else argv)]
    config = config_from_args(parser, args, command)
    if args.export is not None:
        existing = [path for path in export_files(args.export) if path.exists()]
        if existing and not args.overwrite:
            parser.error(f"argument --export: {existing[0]} exists; pass --overwrite to replace it")
    default = default_run_dir(args.env, args.algo, args.n_trailers, args.seed)
    try:
        run_dir = choose_run_dir(default, args.run_dir, args.resume, args.overwrite)
    except RunFolderError as error:
        parser.error(f"argument --run-dir: {error}")
    limit_torch_threads(args.torch_threads)
    started = time.perf_counter()
    if args.backend == "rllib":
        from agents.rllib_backend import train_rllib

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
        print(
            f"trained ppo on {args.env} (n = {args.n_trailers}) with RLlib to "
            f"{record['timesteps']} steps in {time.perf_counter() - started:.0f} s "
            f"({record['env_steps_per_s']:.0f} env steps/s, {args.num_env_runners} runners); "
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
