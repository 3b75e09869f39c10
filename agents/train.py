"""Train a stable-baselines3 agent on a trailer_env scene through the native batched env.

Usage::

    python -m agents.train --env trailer_env/Reverse-v0 --algo ppo --n-trailers 2 \\
        --timesteps 1000000 --seed 0

Hyperparameters come from ``agents/hyperparams/<algo>.yml`` (rl-zoo3 format). The
run folder (default ``runs/<scene>_n<n>_<algo>_s<seed>``) receives:

* ``config.json``: the command's arguments and the hyperparameters used;
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
already holds another run is refused unless ``--overwrite``.

``--export PATH`` copies the best model, its card, statistics and learning curve to
PATH (e.g. ``agents/models/``); existing files there are refused unless ``--overwrite``.

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
import json
import shutil
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from agents.config import Hyperparams, load_hyperparams
from agents.envs import ENV_IDS, env_settings, make_sb3_env, scene_of
from agents.model_files import (
    UnsafeFileError,
    load_pickled_stats,
    load_sb3,
    read_stats,
    restore_stats,
    save_stats,
)
from agents.policies import (
    ALGOS,
    algo_class,
    card_path,
    detect_algo,
    limit_torch_threads,
    load_model,
    pickled_stats_path,
    stats_path,
)


def default_run_dir(env_id: str, algo: str, n_trailers: int, seed: int) -> Path:
    """``runs/<scene>_n<n>_<algo>_s<seed>``."""
    return Path("runs") / f"{scene_of(env_id)}_n{n_trailers}_{algo}_s{seed}"


def _positive_int(text: str) -> int:
    try:
        value = int(float(text))
    except (ValueError, OverflowError):  # "abc", "nan"; "inf"
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1 or value != float(text):
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def _non_negative_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}")
    return value


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
    parser.add_argument(
        "--env",
        required=True,
        choices=ENV_IDS,
        metavar="ENV_ID",
        help=f"environment id, one of {', '.join(ENV_IDS)}",
    )
    parser.add_argument("--algo", required=True, choices=sorted(ALGOS), help="algorithm")
    parser.add_argument(
        "--n-trailers", type=_non_negative_int, default=2, help="number of trailers (default 2)"
    )
    parser.add_argument(
        "--timesteps",
        type=_positive_int,
        default=None,
        help="total training budget in environment steps "
        "(default: n_timesteps of the hyperparameter file)",
    )
    parser.add_argument("--seed", type=_non_negative_int, default=0, help="random seed")
    parser.add_argument(
        "--n-envs",
        type=_positive_int,
        default=None,
        help="environments per batch (default: from the hyperparameters); "
        "with --backend rllib: per env runner",
    )
    parser.add_argument(
        "--num-env-runners",
        type=_non_negative_int,
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
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="start afresh in a run folder that already holds a run; replace --export's files",
    )
    parser.add_argument(
        "--trust-pickle",
        action="store_true",
        help="allow unpickling parts of --resume's files (SB3 serialized entries, SAC/TD3 "
        "replay buffers, legacy .pkl statistics): only for files you trust",
    )
    parser.add_argument(
        "--eval-freq",
        type=_positive_int,
        default=None,
        help="steps between evaluations (default: budget / 20)",
    )
    parser.add_argument(
        "--eval-episodes",
        type=_positive_int,
        default=50,
        help="episodes per evaluation (default 50)",
    )
    parser.add_argument(
        "--checkpoint-freq",
        type=_positive_int,
        default=None,
        help="steps between checkpoints (default: budget / 5)",
    )
    parser.add_argument(
        "--export", type=Path, default=None, help="copy the best model (+ card, curve) to this .zip"
    )
    parser.add_argument(
        "--torch-threads", type=_positive_int, default=1, help="torch CPU threads (default 1)"
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--quiet", action="store_true", help="no evaluation lines")
    return parser


def _progress_bar_available() -> bool:
    return all(importlib.util.find_spec(name) is not None for name in ("tqdm", "rich"))


def _jsonable(value: Any) -> Any:
    """Hyperparameter values as JSON (schedules and classes by name)."""
    if isinstance(value, dict):
        return {str(key): _jsonable(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(item) for item in value]
    if isinstance(value, (bool, int, float, str)) or value is None:
        return value
    return getattr(value, "__name__", repr(value))


def write_card(model_path: Path, card: dict[str, Any]) -> None:
    """Write the model card (JSON beside the model) that :mod:`agents.policies` reads."""
    card_path(model_path).write_text(json.dumps(card, indent=2, sort_keys=True) + "\n")


def export_files(destination: Path) -> list[Path]:
    """The files :func:`export_model` writes for ``destination``: model, card, statistics, curve."""
    model = destination.with_suffix(".zip")
    return [model, card_path(model), stats_path(model), model.with_suffix(".csv")]


def export_model(run_dir: Path, destination: Path, overwrite: bool = False) -> Path:
    """Copy ``best_model.zip``, its card, statistics and ``evaluations.csv`` to ``destination``.

    Raises:
        FileNotFoundError: If the run has no best model.
        FileExistsError: If one of the destination files exists and ``overwrite`` is false.
    """
    source = run_dir / "best_model.zip"
    if not source.is_file():
        raise FileNotFoundError(f"{run_dir} has no best_model.zip to export")
    existing = [path for path in export_files(destination) if path.exists()]
    if existing and not overwrite:
        raise FileExistsError(f"{existing[0]} exists; pass --overwrite to replace it")
    destination = destination.with_suffix(".zip")
    destination.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(source, destination)
    for sidecar in (card_path, stats_path):
        if sidecar(source).is_file():
            shutil.copyfile(sidecar(source), sidecar(destination))
    curve = run_dir / "evaluations.csv"
    if curve.is_file():
        shutil.copyfile(curve, destination.with_suffix(".csv"))
    return destination


def train(
    env_id: str,
    algo: str,
    n_trailers: int,
    timesteps: int | None,
    seed: int,
    run_dir: Path,
    *,
    hyperparams: Hyperparams | None = None,
    n_envs: int | None = None,
    resume: Path | None = None,
    eval_freq: int | None = None,
    eval_episodes: int = 50,
    checkpoint_freq: int | None = None,
    progress_bar: bool = True,
    verbose: int = 1,
    command: list[str] | None = None,
    trust_pickle: bool = False,
) -> Any:
    """Train (or resume) an agent; returns the model. See the module docstring for outputs.

    Args:
        env_id: A trailer_env id.
        algo: "ppo", "sac" or "td3".
        n_trailers: Number of trailers (overrides the hyperparameter file's env_kwargs).
        timesteps: Total budget in environment steps (None: the file's n_timesteps).
        seed: Seed of the model and of the training environments (env i gets seed + i).
        run_dir: Run folder.
        hyperparams: Preprocessed hyperparameters (default: read agents/hyperparams).
        n_envs: Batch size override.
        resume: Checkpoint to continue from.
        eval_freq, eval_episodes, checkpoint_freq: Evaluation and checkpoint schedule.
        progress_bar: Show SB3's progress bar (needs tqdm and rich).
        verbose: 1 prints one line per evaluation.
        command: The command line, recorded in the config and the model cards.
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

    hp = hyperparams if hyperparams is not None else load_hyperparams(algo, env_id)
    env_kwargs = {**hp.env_kwargs, "n_trailers": n_trailers}
    settings = env_settings(env_kwargs)  # fail early on bad settings
    budget = int(timesteps if timesteps is not None else hp.n_timesteps)
    batch = int(n_envs if n_envs is not None else hp.n_envs)
    run_dir.mkdir(parents=True, exist_ok=True)
    start_steps = 0
    venv = make_sb3_env(env_id, batch, env_kwargs, seed=seed)
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
        buffer = _replay_buffer_of(resume)
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
    config = {
        "algo": algo,
        "env_id": env_id,
        "env_kwargs": env_kwargs,
        "seed": seed,
        "budget": budget,
        "n_envs": batch,
        "policy": hp.policy,
        "hyperparams": _jsonable(hp.algo_kwargs),
        "normalize": hp.normalize,
        "command": command or [],
    }
    (run_dir / "config.json").write_text(json.dumps(config, indent=2, sort_keys=True) + "\n")
    remaining = budget - start_steps
    if remaining <= 0:
        if verbose:
            print(f"{resume} is already at {start_steps} >= {budget} steps: nothing to train")
        return model
    evaluator = SafetyEvalCallback(
        env_id,
        env_kwargs,
        run_dir,
        eval_freq=eval_freq or max(budget // 20, batch),
        episodes=eval_episodes,
        resume_from=start_steps if resume is not None else None,
        verbose=verbose,
    )
    checkpoints = StatsCheckpointCallback(
        save_freq=max((checkpoint_freq or max(budget // 5, batch)) // batch, 1),
        save_path=str(run_dir / "checkpoints"),
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
    config.update({"timesteps": int(model.num_timesteps), "wall_time_s": wall})
    final = run_dir / "final_model.zip"
    model.save(final)
    stats = model.get_vec_normalize_env()
    if stats is not None:
        save_stats(stats, stats_path(final))
    write_card(final, config)
    best = run_dir / "best_model.zip"
    if best.is_file():
        selection = json.loads(card_path(best).read_text())
        write_card(best, {**config, **selection})
    return model


def _replay_buffer_of(checkpoint: Path) -> Path | None:
    """The replay buffer CheckpointCallback saved with ``<algo>_<steps>_steps.zip``, if any."""
    stem = checkpoint.stem
    if not stem.endswith("_steps"):
        return None
    prefix = stem.removesuffix("_steps")
    algo, _, steps = prefix.rpartition("_")
    candidate = checkpoint.with_name(f"{algo}_replay_buffer_{steps}_steps.pkl")
    return candidate if candidate.is_file() else None


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


def run_dir_of_checkpoint(checkpoint: Path) -> Path | None:
    """The run folder a checkpoint belongs to, or None when it is in none.

    A checkpoint belongs to a run when it lies in the run's folder or in its
    ``checkpoints/`` subfolder and that folder holds the run's ``config.json``.
    Anything else (a shipped model in ``agents/models/``, a downloaded file) is not
    in a run: resuming it starts a fresh run folder, it never turns the file's folder
    into one.
    """
    parent = checkpoint.resolve().parent
    folder = parent.parent if parent.name == "checkpoints" else parent
    return folder if (folder / "config.json").is_file() else None


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
        buffer = _replay_buffer_of(args.resume)
        if buffer is not None and not args.trust_pickle:
            raise UnsafeFileError(
                f"its replay buffer {buffer} is a pickle; pass --trust-pickle to load it "
                "(only if you trust the file)"
            )
    except (ValueError, FileNotFoundError) as error:
        parser.error(f"argument --resume: {error}")


def _choose_run_dir(parser: argparse.ArgumentParser, args: argparse.Namespace) -> Path:
    """The run folder: --run-dir, the resumed checkpoint's run, or a fresh default.

    A fresh start (or a resume into a folder that is not the checkpoint's run)
    refuses a folder that already holds a run unless --overwrite, which clears it.
    """
    own_run = run_dir_of_checkpoint(args.resume) if args.resume is not None else None
    run_dir = (
        args.run_dir or own_run or default_run_dir(args.env, args.algo, args.n_trailers, args.seed)
    )
    if run_dir.exists() and not run_dir.is_dir():
        parser.error(f"argument --run-dir: {run_dir} exists and is not a folder")
    continuing = own_run is not None and run_dir.resolve() == own_run
    holds_run = (run_dir / "evaluations.csv").exists() or (run_dir / "config.json").exists()
    if not continuing and holds_run:
        if not args.overwrite:
            parser.error(
                f"argument --run-dir: {run_dir} already holds a run; pass --resume "
                "<checkpoint>, another --run-dir, or --overwrite"
            )
        for stale in (
            "evaluations.csv",
            "config.json",
            "progress.csv",
            "best_model.zip",
            "best_model.json",
            "best_model_vecnormalize.json",
            "best_model_vecnormalize.pkl",
        ):
            (run_dir / stale).unlink(missing_ok=True)
        for folder in ("checkpoints", "checkpoint"):
            shutil.rmtree(run_dir / folder, ignore_errors=True)
    return run_dir


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2, with a message)."""
    parser = build_parser()
    args = parser.parse_args(argv)
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
    if args.resume is not None:
        _check_resume(parser, args)
    try:
        hp = (
            load_hyperparams(args.algo, args.env, args.hyperparams)
            if args.hyperparams is not None
            else load_hyperparams(args.algo, args.env)
        )
    except (FileNotFoundError, KeyError, ValueError) as error:
        parser.error(f"argument --hyperparams: {str(error).strip(chr(34) + chr(39))}")
    try:
        env_settings({**hp.env_kwargs, "n_trailers": args.n_trailers})
    except (TypeError, ValueError) as error:
        parser.error(f"argument --n-trailers (or the file's env_kwargs): {error}")
    if args.export is not None:
        existing = [path for path in export_files(args.export) if path.exists()]
        if existing and not args.overwrite:
            parser.error(f"argument --export: {existing[0]} exists; pass --overwrite to replace it")
    run_dir = _choose_run_dir(parser, args)
    limit_torch_threads(args.torch_threads)
    started = time.perf_counter()
    command = ["python", "-m", "agents.train", *(sys.argv[1:] if argv is None else argv)]
    if args.backend == "rllib":
        from agents.rllib_backend import train_rllib

        try:
            record = train_rllib(
                args.env,
                args.algo,
                args.n_trailers,
                args.timesteps,
                args.seed,
                run_dir,
                hyperparams=hp,
                num_env_runners=args.num_env_runners,
                envs_per_runner=args.n_envs,
                address=args.address,
                verbose=0 if args.quiet else 1,
                command=command,
            )
        except ConnectionError as error:
            parser.error(f"argument --address: {error}")
        print(
            f"trained ppo on {args.env} (n = {args.n_trailers}) with RLlib to "
            f"{record['timesteps']} steps in {time.perf_counter() - started:.0f} s "
            f"({record['env_steps_per_s']:.0f} env steps/s, {args.num_env_runners} runners); "
            f"checkpoint {run_dir / 'checkpoint'}"
        )
        return 0
    model = train(
        args.env,
        args.algo,
        args.n_trailers,
        args.timesteps,
        args.seed,
        run_dir,
        hyperparams=hp,
        n_envs=args.n_envs,
        resume=args.resume,
        eval_freq=args.eval_freq,
        eval_episodes=args.eval_episodes,
        checkpoint_freq=args.checkpoint_freq,
        progress_bar=not args.no_progress,
        verbose=0 if args.quiet else 1,
        command=command,
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
