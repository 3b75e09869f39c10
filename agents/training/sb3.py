"""Training a stable-baselines3 agent through the native batch (the library of agents.train)."""

from __future__ import annotations

import importlib.util
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from agents.algorithms import algorithm
from agents.algorithms.options import FineTune
from agents.artifacts.cards import ModelCard, read_model_card, write_card
from agents.artifacts.paths import pickled_stats_path, replay_buffer_path, stats_path
from agents.artifacts.run_folder import (
    BEST_MODEL,
    CHECKPOINTS,
    CURVE_FILE,
    FINAL_MODEL,
    resume_problem,
    with_curve_validation,
    write_config,
)
from agents.artifacts.sb3_zip import UnsafeFileError, algo_class, load_sb3, save_model
from agents.artifacts.stats import load_pickled_stats, read_stats, restore_stats, save_stats
from agents.envs import make_sb3_env, settings_by_count
from agents.policies.extractors import feature_extractors
from agents.training.config import TrainConfig

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecEnv

    from agents.training.callbacks import EvaluationHook, StatsCheckpointCallback


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
) -> BaseAlgorithm:
    """Train (or resume) an SB3 agent; returns the model. See the module docstring for outputs.

    Args:
        config: What to train (:meth:`agents.training.config.TrainConfig.resolve`); each of
            its options sets the training environment up and adds its callbacks.
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

    from agents.training.callbacks import PlateauStop, ProgressCallback, SafetyEvalCallback
    from agents.training.host_speed import measure_host_speed

    action_dim = _flat_action_dim(config)
    run_dir.mkdir(parents=True, exist_ok=True)
    venv = _training_env(config, resume, trust_pickle)
    model = _model(config, venv, action_dim, resume, trust_pickle)
    start_steps = int(model.num_timesteps) if resume is not None else 0
    if resume is not None:
        _go_on_from(model, venv, config, run_dir, resume, trust_pickle)
    outputs = ("csv", "tensorboard") if importlib.util.find_spec("tensorboard") else ("csv",)
    model.set_logger(configure(str(run_dir / "logs" / f"from_{start_steps}"), list(outputs)))
    record = ModelCard.from_json(config.document(), f"of {run_dir}").replace(
        host=measure_host_speed(config.seed)
    )
    write_config(run_dir, record)
    evaluator = SafetyEvalCallback(
        config.env_id,
        config.env_kwargs,
        run_dir,
        eval_freq=eval_freq or max(config.budget // 20, config.n_envs),
        episodes=eval_episodes,
        resume_from=start_steps if resume is not None else None,
        verbose=verbose,
        hooks=hooks,
        record=record.to_json(),
    )
    plateau = None
    if stop_on_plateau is not None:
        previous = [(row["timesteps"], row[evaluator.metric]) for row in evaluator.previous_rows]
        plateau = PlateauStop(evaluator.metric, *stop_on_plateau, previous=previous)
        evaluator.hooks.append(plateau)
    callbacks: list[BaseCallback] = [evaluator, _checkpoints(config, run_dir, checkpoint_freq)]
    for option in config.options:
        option.prepare(venv, seed=config.seed, start_steps=start_steps)
        callbacks.extend(option.callbacks())
    if progress_bar:
        callbacks.append(ProgressCallback(f"training {config.algo} on {config.env_id}"))
    model.learn(
        total_timesteps=config.budget - start_steps,
        callback=callbacks,
        reset_num_timesteps=resume is None,
    )
    stopped_at = None if plateau is None else plateau.stopped_at
    card = record.replace(
        timesteps=int(model.num_timesteps),
        wall_time_s=round(evaluator.wall_seconds, 1),
        stopped_on_plateau_at=stopped_at,
    )
    if plateau is not None and stopped_at is not None and verbose:
        print(
            f"the validation {plateau.metric} is flat ({plateau.window} evaluations "
            f"within {plateau.eps:g}, its last third not rising): stopped at "
            f"{stopped_at} steps"
        )
    _save_final(model, run_dir, card)
    return model


def _flat_action_dim(config: TrainConfig) -> int:
    """The run's action dimension, its settings checked first (every count of a range
    shares the observation kind and the action space).

    Raises:
        ValueError: If the environment's observation is not the flat one.
    """
    settings = next(iter(settings_by_count(config.env_kwargs).values()))
    if settings.observation != "flat":
        # Its evaluations score on the flat observation and its statistics files hold one
        # array; SB3 trains on the Dict directly (docs/agents.md, ConvoyEncoder).
        raise ValueError(
            f"agents.train needs the flat observation, got observation={settings.observation!r}"
            "; train SB3 on ConvoySB3VecEnv(..., observation='trailers') directly"
        )
    return int(settings.action_dim)


def _training_env(config: TrainConfig, resume: Path | None, trust_pickle: bool) -> VecEnv:
    """The training batch under its options' wrappers (the shaping) and normalisation
    (statistics restored from ``resume`` or a fine-tuning run's source, and frozen for the
    latter)."""
    from stable_baselines3.common.vec_env import VecNormalize

    hp = config.hyperparams
    gamma = hp.gamma
    venv: VecEnv = make_sb3_env(config.env_id, config.n_envs, config.env_kwargs, seed=config.seed)
    for option in config.options:
        # Under the normalisation, so its statistics (and the policy) see the scene's states.
        venv = option.wrap(venv, gamma=gamma)
    if hp.normalize is None:
        return venv
    normalized = VecNormalize(venv, **{"gamma": gamma, **hp.normalize})
    fine_tune = config.option(FineTune)
    source = resume if resume is not None else None if fine_tune is None else fine_tune.source
    if source is not None:
        _restore_checkpoint_stats(normalized, source, trust_pickle)
    if fine_tune is not None:
        # The starting policy reads its inputs through these statistics: letting them
        # drift would change its decisions under it (docs/agents.md, fine-tuning).
        normalized.training = False
    return normalized


def _model(
    config: TrainConfig, venv: VecEnv, action_dim: int, resume: Path | None, trust_pickle: bool
) -> BaseAlgorithm:
    """The model to train: ``resume``'s, a fine-tuning run's start, or a fresh one."""
    from stable_baselines3.common.noise import NormalActionNoise

    hp = config.hyperparams
    kwargs = dict(hp.algo_kwargs)
    if "policy_kwargs" in kwargs:
        # SB3 adds its own entries to the dict it is given (SAC: use_sde); the run's
        # record keeps the file's (the property is a copy).
        kwargs.update(policy_kwargs=hp.policy_kwargs)
    if hp.action_noise_std is not None:
        noise = hp.action_noise_std * np.ones(action_dim)
        kwargs.update(action_noise=NormalActionNoise(np.zeros(action_dim), noise))
    fine_tune = config.option(FineTune)
    if resume is not None:
        return load_sb3(
            resume,
            config.algo,
            venv.observation_space,
            venv.action_space,
            env=venv,
            algo_kwargs=kwargs,
            trust_pickle=trust_pickle,
            extractors=feature_extractors(),
        )
    if fine_tune is not None:
        return _initialised(fine_tune.source, config, venv, kwargs, trust_pickle)
    return algo_class(config.algo)(
        hp.policy, venv, seed=config.seed, device="cpu", verbose=0, **kwargs
    )


def _go_on_from(
    model: BaseAlgorithm,
    venv: VecEnv,
    config: TrainConfig,
    run_dir: Path,
    resume: Path,
    trust_pickle: bool,
) -> None:
    """Check a resumed run against its budget and folder, reseed it and load its replay
    buffer.

    Raises:
        ValueError: If the checkpoint is at the budget or more, or the run folder's files
            cannot be read back.
        UnsafeFileError: If its replay buffer is a pickle and ``trust_pickle`` is false.
    """
    start_steps = int(model.num_timesteps)
    if start_steps >= config.budget:
        raise ValueError(
            f"{resume} is at {start_steps} steps; the run's total budget must be above "
            f"that, got {config.budget}"
        )
    problem = resume_problem(run_dir)
    if problem is not None:
        raise ValueError(f"cannot resume into {run_dir}: {problem}")
    # Fresh starting states, not a replay of those before the resume.
    venv.seed(config.seed + start_steps)
    model.set_random_seed(config.seed + start_steps)
    buffer = replay_buffer_path(resume)
    if buffer is not None and hasattr(model, "load_replay_buffer"):
        if not trust_pickle:
            raise UnsafeFileError(
                f"the replay buffer {buffer} is a pickle; pass --trust-pickle to load it"
            )
        model.load_replay_buffer(buffer)


def _checkpoints(
    config: TrainConfig, run_dir: Path, checkpoint_freq: int | None
) -> StatsCheckpointCallback:
    """The checkpoint callback (its replay buffer too for off-policy algorithms)."""
    from agents.training.callbacks import StatsCheckpointCallback

    batch = config.n_envs
    return StatsCheckpointCallback(
        save_freq=max((checkpoint_freq or max(config.budget // 5, batch)) // batch, 1),
        save_path=str(run_dir / CHECKPOINTS),
        name_prefix=config.algo,
        save_replay_buffer=algorithm(config.algo).off_policy,
    )


def _save_final(model: BaseAlgorithm, run_dir: Path, card: ModelCard) -> None:
    """Save the final model with its statistics and ``card`` (its validation the curve's
    row at its last step, where it was evaluated), and complete the best
    model's card with the run's totals (what it holds of its own, such as when it was
    selected, stays)."""
    final = run_dir / FINAL_MODEL
    stats = model.get_vec_normalize_env()
    if stats is not None:
        save_stats(stats, stats_path(final))
    write_card(final, with_curve_validation(card, run_dir / CURVE_FILE))
    save_model(model, final)
    best = run_dir / BEST_MODEL
    if best.is_file():
        own = read_model_card(best).to_json()
        write_card(best, ModelCard.from_json({**card.to_json(), **own}, str(best)))


def _initialised(
    source_path: Path,
    config: TrainConfig,
    venv: VecEnv,
    algo_kwargs: dict[str, object],
    trust_pickle: bool,
) -> BaseAlgorithm:
    """A fresh model of the run's hyperparameters whose policy is ``source_path``'s.

    The network (``policy_kwargs``: layers, extractor, log standard deviation) is the
    source's, so its weights fit; everything else (learning rate, clipping, horizon) is
    the run's.

    Raises:
        ValueError: If the source cannot be loaded safely as ``algo`` for this env.
    """
    algo = config.algo
    source = load_sb3(
        source_path,
        algo,
        venv.observation_space,
        venv.action_space,
        algo_kwargs=algo_kwargs,
        trust_pickle=trust_pickle,
        extractors=feature_extractors(),
    )
    policy_kwargs = {**config.hyperparams.policy_kwargs, **source.policy_kwargs}
    kwargs = {**algo_kwargs, "policy_kwargs": policy_kwargs}
    model: BaseAlgorithm = algo_class(algo)(
        config.hyperparams.policy, venv, seed=config.seed, device="cpu", verbose=0, **kwargs
    )
    model.policy.load_state_dict(source.policy.state_dict())
    return model


def _restore_checkpoint_stats(venv: VecEnv, checkpoint: Path, trust_pickle: bool) -> None:
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
