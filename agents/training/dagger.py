"""DAgger's steps: label the states a driver visits (:func:`collect`), fit the student's
mean action to the labels (:func:`fit`), and the student to fit (:func:`build_student`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np

from agents.envs import make_sb3_env
from agents.oracles.labellers import Labeller
from agents.oracles.planner import SamplingPlanner
from agents.policies.convoy_order import CONVOY_DIRECTIONS
from agents.policies.extractors import feature_extractor
from agents.progress import Progress
from agents.training.config import load_hyperparams
from agents.training.imitation_config import ImitationConfig
from trailer_env.observation import flat_observation
from trailer_env.vector import ConvoyVectorEnv

if TYPE_CHECKING:
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from trailer_env.core import ConvoyCore

#: Floor of the observations' variance in the frozen statistics. The cosines of nearly
#: straight hitch angles vary by about 1e-5 over the expert's data: unfloored, the policy
#: would read them amplified 300-fold and see inputs far outside its data as soon as an
#: angle grows (the edge of the basin, where the actions matter most).
OBS_VAR_FLOOR = 1e-3

#: Log standard deviation the saved policy explores with when fine-tuned by PPO
#: (the imitation fits the mean only).
FINE_TUNE_LOG_STD = -2.5

#: A driver of the labelling envs: flat observations (E, d) to actions (E, 1).
Driver = Callable[[np.ndarray], np.ndarray]


def collect(
    envs: ConvoyVectorEnv,
    planner: Labeller | SamplingPlanner,
    policy: Driver | None,
    seed: int,
    progress: Progress | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """One iteration's data: observations and the planner's actions at every visited state.

    ``progress`` (counting labelled steps) advances once per step.

    ``policy`` None lets the planner drive. ``envs`` must reset in the same step
    (``autoreset_mode="same_step"``) so that each observation is the core's state.
    """
    reset_obs, _ = envs.reset(seed=seed)
    obs = flat_observation(reset_obs, "DAgger's labelling")
    planner.reset()
    core = cast("ConvoyCore", envs.core)  # a scene's core, or a MixedCore over several n
    steps = envs.max_episode_steps
    observations = np.empty((steps, *obs.shape), dtype=np.float32)
    labels = np.empty((steps, envs.num_envs), dtype=np.float64)
    for t in range(steps):
        label = planner.label(core)
        observations[t] = obs
        labels[t] = label[:, 0]
        action = label if policy is None else policy(obs)
        stepped, _, terminated, truncated, _ = envs.step(np.asarray(action, dtype=np.float32))
        obs = flat_observation(stepped, "DAgger's labelling")
        ended = np.flatnonzero(terminated | truncated)
        if ended.size:
            planner.reset(ended)
        if progress is not None:
            progress.advance(f"labelling step {t + 1}")
    return observations.reshape(-1, obs.shape[1]), labels.reshape(-1, 1)


def fit(
    model: PPO,
    obs: np.ndarray | dict[str, np.ndarray],
    labels: np.ndarray,
    config: ImitationConfig,
    rng: np.random.Generator,
) -> float:
    """Fit the policy's mean action to ``labels`` (``obs``: normalised flat observations,
    or the dict of ``observation="trailers"``); the last epoch's loss."""
    import torch

    policy = model.policy
    policy.set_training_mode(True)
    optimizer = torch.optim.Adam(policy.parameters(), lr=config.learning_rate)
    inputs: torch.Tensor | dict[str, torch.Tensor] = (
        {key: torch.as_tensor(value, dtype=torch.float32) for key, value in obs.items()}
        if isinstance(obs, dict)
        else torch.as_tensor(obs, dtype=torch.float32)
    )
    targets = torch.as_tensor(labels, dtype=torch.float32)
    loss_sum = 0.0
    for _ in range(config.epochs):
        order = torch.as_tensor(rng.permutation(len(targets)))
        loss_sum, batches = 0.0, 0
        for start in range(0, len(order), config.batch_size):
            rows = order[start : start + config.batch_size]
            batch = (
                {key: value[rows] for key, value in inputs.items()}
                if isinstance(inputs, dict)
                else inputs[rows]
            )
            mean = policy.get_distribution(batch).distribution.mean  # type: ignore[union-attr]
            loss = torch.mean((mean - targets[rows]) ** 2)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            loss_sum += loss.item()
            batches += 1
        loss_sum /= max(batches, 1)
    policy.set_training_mode(False)
    return loss_sum


@dataclass(frozen=True)
class Student:
    """The policy DAgger fits, before its first fit.

    Attributes:
        model: The PPO model (untrained).
        stats: Its observation statistics, frozen (None with "trailers").
        settings: The hyperparameters used but the policy's keywords (with ``n_envs``).
        policy_kwargs: The policy's keywords (with the features extractor's class).
    """

    model: PPO
    stats: VecNormalize | None
    settings: dict[str, object]
    policy_kwargs: dict[str, object]


def build_student(config: ImitationConfig) -> Student:
    """The student of ``config``: PPO's policy of the hyperparameter file's entry (its
    ``net_arch`` replaced by the config's) reading normalised flat observations, or the
    Dict of "trailers" through :class:`~agents.policies.convoy_encoder.ConvoyEncoder`."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    hp = load_hyperparams("ppo", config.env_id)
    architecture = {} if config.net_arch is None else {"net_arch": list(config.net_arch)}
    policy_kwargs = {**hp.policy_kwargs, **architecture, "log_std_init": FINE_TUNE_LOG_STD}
    others = {key: value for key, value in hp.algo_kwargs.items() if key != "policy_kwargs"}
    settings = {"n_envs": hp.n_envs, **others}
    if config.observation == "trailers":
        extractor: dict[str, object] = {
            "features_extractor_class": feature_extractor("ConvoyEncoder")
        }
        if config.convoy_direction != CONVOY_DIRECTIONS[0]:  # default runs keep their saved kwargs
            given = policy_kwargs.get("features_extractor_kwargs")
            extractor["features_extractor_kwargs"] = {
                **(given if isinstance(given, dict) else {}),
                "direction": config.convoy_direction,
            }
        policy_kwargs.update(extractor)
        venv = make_sb3_env(config.env_id, hp.n_envs, config.student_kwargs, seed=config.seed)
        model = PPO(
            "MultiInputPolicy",
            venv,
            seed=config.seed,
            device="cpu",
            verbose=0,
            **others,
            policy_kwargs=policy_kwargs,
        )
        return Student(model, None, settings, policy_kwargs)
    venv = make_sb3_env(config.env_id, hp.n_envs, config.env_kwargs, seed=config.seed)
    stats = VecNormalize(venv, norm_obs=True, norm_reward=False, gamma=hp.gamma, training=False)
    model = PPO(
        hp.policy,
        stats,
        seed=config.seed,
        device="cpu",
        verbose=0,
        **others,
        policy_kwargs=policy_kwargs,
    )
    return Student(model, stats, settings, policy_kwargs)


def freeze_statistics(stats: VecNormalize, obs: np.ndarray) -> None:
    """Set the student's observation statistics from the first iteration's data, the
    variances floored at :data:`OBS_VAR_FLOOR` (then frozen for the run)."""
    rms = stats.obs_rms
    assert not isinstance(rms, dict)  # the flat observation: one array
    rms.mean = obs.mean(axis=0).astype(np.float64)
    rms.var = np.maximum(obs.var(axis=0), OBS_VAR_FLOOR).astype(np.float64)
    rms.count = float(len(obs))
