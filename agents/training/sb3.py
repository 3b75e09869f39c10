"""Training a stable-baselines3 agent through the native batch (the library of agents.train)."""

from __future__ import annotations

import importlib.util
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from agents.algorithms import algorithm
from agents.artifacts.cards import read_card, write_card
from agents.artifacts.paths import pickled_stats_path, replay_buffer_path, stats_path
from agents.artifacts.run_folder import (
    BEST_MODEL,
    CHECKPOINTS,
    FINAL_MODEL,
    resume_problem,
    write_config,
)
from agents.artifacts.sb3_zip import UnsafeFileError, algo_class, load_sb3, save_model
from agents.artifacts.stats import load_pickled_stats, read_stats, restore_stats, save_stats
from agents.envs import make_sb3_env, settings_by_count
from agents.policies.extractors import feature_extractors
from agents.training.config import TrainConfig

if TYPE_CHECKING:
    from agents.training.callbacks import EvaluationHook


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
    stop_on_plateau: tuple[int, float] | None = None,
    hooks: Sequence[EvaluationHook] = (),
) -> Any:
    """Train (or resume) an SB3 agent; returns the model. See the module docstring for outputs.

    Args:
        config: What to train (:meth:`agents.training.config.TrainConfig.resolve`).
        run_dir: Run folder.
        resume: Checkpoint to continue from.
        eval_freq, eval_episodes, checkpoint_freq: Evaluation and checkpoint schedule.
        progress_bar: Report progress with counts and an ETA on standard error, ending
            at the step count the run reaches (:class:`agents.training.callbacks.ProgressCallback`).
        verbose: 1 prints one line per evaluation.
        trust_pickle: Allow unpickling ``resume``'s pickled parts (serialized entries,
            replay buffer, legacy statistics); otherwise they are replaced or refused
            (:mod:`agents.artifacts`).
        stop_on_plateau: (window, eps): stop once the validation headline rate is flat
            for ``window`` evaluations and its end no longer rises
            (:class:`agents.training.callbacks.PlateauStop`); the cards then record
            ``stopped_on_plateau_at`` (the step).
        hooks: More :data:`~agents.training.callbacks.EvaluationHook` s (e.g. a tuner's
            pruner): each evaluation is passed on; one returning True stops the run.

    Raises:
        ValueError: Before anything is written: if ``resume`` cannot be loaded safely (or
            at all), is already at ``config.budget`` steps or more, or ``run_dir``'s curve
            or best model's card is unreadable
            (:func:`~agents.artifacts.run_folder.resume_problem`); or if the environment has
            ``observation="trailers"`` (not supported here yet).
    """
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.noise import NormalActionNoise
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.training.callbacks import (
        CriticWarmup,
        PlateauStop,
        ProgressCallback,
        SafetyEvalCallback,
        StartCurriculum,
        StartReplayStats,
        StatsCheckpointCallback,
    )
    from trailer_env.sb3 import PotentialShapingVecEnv
    from trailer_env.start_replay import StartReplay

    hp = config.hyperparams
    algo, seed, budget, batch = config.algo, config.seed, config.budget, config.n_envs
    env_kwargs = config.env_kwargs
    # Fail early on bad settings; every count of a range shares the observation kind and
    # the action space.
    settings = next(iter(settings_by_count(env_kwargs).values()))
    if settings.observation != "flat":
        # Its evaluations score on the flat observation and its statistics files hold one
        # array; SB3 trains on the Dict directly (docs/agents.md, ConvoyEncoder).
        raise ValueError(
            f"agents.train needs the flat observation, got observation={settings.observation!r}"
            "; train SB3 on ConvoySB3VecEnv(..., observation='trailers') directly"
        )
    run_dir.mkdir(parents=True, exist_ok=True)
    start_steps = 0
    venv = make_sb3_env(config.env_id, batch, env_kwargs, seed=seed)
    if config.start_replay is not None:
        # Its buffer is not checkpointed: a resumed run starts with an empty one.
        replay = StartReplay(config.start_replay, seed=seed, max_replays=config.start_replay_max)
        venv.set_start_replay(replay)
    if hp.shaping is not None:
        # Under the normalisation, so its statistics (and the policy) see the scene's states.
        venv = PotentialShapingVecEnv(venv, gamma=hp.algo_kwargs.get("gamma", 0.99), **hp.shaping)
    if hp.normalize is not None:
        normalize = {"gamma": hp.algo_kwargs.get("gamma", 0.99), **hp.normalize}
        venv = VecNormalize(venv, **normalize)
        if resume is not None:
            _restore_checkpoint_stats(venv, resume, trust_pickle)
        elif config.init_from is not None:
            _restore_checkpoint_stats(venv, Path(config.init_from), trust_pickle)
        if config.init_from is not None:
            # The starting policy reads its inputs through these statistics: letting them
            # drift would change its decisions under it (docs/agents.md, fine-tuning).
            venv.training = False
    kwargs = dict(hp.algo_kwargs)
    if isinstance(kwargs.get("policy_kwargs"), dict):
        # SB3 adds its own entries to the dict it is given (SAC: use_sde); the run's
        # record keeps the file's.
        kwargs["policy_kwargs"] = dict(kwargs["policy_kwargs"])
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
            extractors=feature_extractors(),
        )
        start_steps = int(model.num_timesteps)
        if start_steps >= budget:
            raise ValueError(
                f"{resume} is at {start_steps} steps; the run's total budget must be above "
                f"that, got {budget}"
            )
        problem = resume_problem(run_dir)
        if problem is not None:
            raise ValueError(f"cannot resume into {run_dir}: {problem}")
        # Fresh starting states, not a replay of those before the resume.
        venv.seed(seed + start_steps)
        model.set_random_seed(seed + start_steps)
        buffer = replay_buffer_path(resume)
        if buffer is not None and hasattr(model, "load_replay_buffer"):
            if not trust_pickle:
                raise UnsafeFileError(
                    f"the replay buffer {buffer} is a pickle; pass --trust-pickle to load it"
                )
            model.load_replay_buffer(buffer)
    elif config.init_from is not None:
        model = _initialised(
            Path(config.init_from), algo, hp.policy, venv, kwargs, seed, trust_pickle
        )
    else:
        model = algo_class(algo)(hp.policy, venv, seed=seed, device="cpu", verbose=0, **kwargs)
    outputs = ["csv"]
    if importlib.util.find_spec("tensorboard") is not None:
        outputs.append("tensorboard")
    model.set_logger(configure(str(run_dir / "logs" / f"from_{start_steps}"), outputs))
    record = config.document()
    write_config(run_dir, record)
    remaining = budget - start_steps
    evaluator = SafetyEvalCallback(
        config.env_id,
        env_kwargs,
        run_dir,
        eval_freq=eval_freq or max(budget // 20, batch),
        episodes=eval_episodes,
        resume_from=start_steps if resume is not None else None,
        verbose=verbose,
        hooks=hooks,
        record=record,
    )
    plateau = None
    if stop_on_plateau is not None:
        previous = [(row["timesteps"], row[evaluator.metric]) for row in evaluator.previous_rows]
        plateau = PlateauStop(evaluator.metric, *stop_on_plateau, previous=previous)
        evaluator.hooks.append(plateau)
    checkpoints = StatsCheckpointCallback(
        save_freq=max((checkpoint_freq or max(budget // 5, batch)) // batch, 1),
        save_path=str(run_dir / CHECKPOINTS),
        name_prefix=algo,
        save_replay_buffer=algorithm(algo).off_policy,
    )
    callbacks: list[Any] = [evaluator, checkpoints]
    if config.critic_warmup:
        callbacks.append(CriticWarmup(config.critic_warmup))
    if config.start_curriculum is not None:
        curriculum = StartCurriculum(*config.start_curriculum)
        curriculum.apply(venv, start_steps)
        callbacks.append(curriculum)
    if config.start_replay is not None:
        callbacks.append(StartReplayStats())
    if progress_bar:
        callbacks.append(ProgressCallback(f"training {algo} on {config.env_id}"))
    model.learn(total_timesteps=remaining, callback=callbacks, reset_num_timesteps=resume is None)
    wall = round(evaluator.wall_seconds, 1)
    record.update({"timesteps": int(model.num_timesteps), "wall_time_s": wall})
    if plateau is not None and plateau.stopped_at is not None:
        record["stopped_on_plateau_at"] = plateau.stopped_at
        if verbose:
            print(
                f"the validation {plateau.metric} is flat ({plateau.window} evaluations "
                f"within {plateau.eps:g}, its last third not rising): stopped at "
                f"{plateau.stopped_at} steps"
            )
    final = run_dir / FINAL_MODEL
    stats = model.get_vec_normalize_env()
    if stats is not None:
        save_stats(stats, stats_path(final))
    write_card(final, record)
    save_model(model, final)
    best = run_dir / BEST_MODEL
    if best.is_file():
        write_card(best, {**record, **read_card(best)})
    return model


def _initialised(
    source_path: Path,
    algo: str,
    policy: str,
    venv: Any,
    algo_kwargs: dict[str, Any],
    seed: int,
    trust_pickle: bool,
) -> Any:
    """A fresh model of the run's hyperparameters whose policy is ``source_path``'s.

    The network (``policy_kwargs``: layers, extractor, log standard deviation) is the
    source's, so its weights fit; everything else (learning rate, clipping, horizon) is
    the run's.

    Raises:
        ValueError: If the source cannot be loaded safely as ``algo`` for this env.
    """
    source = load_sb3(
        source_path,
        algo,
        venv.observation_space,
        venv.action_space,
        algo_kwargs=algo_kwargs,
        trust_pickle=trust_pickle,
        extractors=feature_extractors(),
    )
    policy_kwargs = {**algo_kwargs.get("policy_kwargs", {}), **source.policy_kwargs}
    kwargs = {**algo_kwargs, "policy_kwargs": policy_kwargs}
    model = algo_class(algo)(policy, venv, seed=seed, device="cpu", verbose=0, **kwargs)
    model.policy.load_state_dict(source.policy.state_dict())
    return model


def _restore_checkpoint_stats(venv: object, checkpoint: Path, trust_pickle: bool) -> None:
    """Put ``checkpoint``'s observation statistics into the (training) ``VecNormalize``.

    Raises:
        UnsafeFileError: If they exist only as a pickle and ``trust_pickle`` is false.
        ValueError: If there are none.
    """
    saved = stats_path(checkpoint)
    if saved.is_file():
        restore_stats(venv, read_stats(saved))
        return
    pickled = pickled_stats_path(checkpoint)
    if pickled is None:
        raise ValueError(
            f"{checkpoint} has no observation statistics ({saved.name}), but the run "
            "normalises observations: it cannot be resumed as it was trained"
        )
    if not trust_pickle:
        raise UnsafeFileError(
            f"the statistics {pickled} are a pickle; pass --trust-pickle to load them"
        )
    loaded = load_pickled_stats(pickled)
    for key in ("obs_rms", "ret_rms", "clip_obs", "clip_reward", "epsilon"):
        setattr(venv, key, getattr(loaded, key))
