"""PPO-Lagrangian: PPO under an episode cost limit on ``info['cost']`` (safety-gym's convention).

The constrained problem is: maximise the return subject to ``E[sum of info['cost'] over
an episode] <= cost_limit``. Its Lagrangian relaxation turns it into a min-max over the
policy and a multiplier ``lambda >= 0`` (Ray, Achiam and Amodei 2019, "Benchmarking Safe
Exploration in Deep Reinforcement Learning"):

* once per rollout, ``lambda`` takes one projected gradient-ascent step on the
  constraint's violation, ``lambda <- max(0, lambda + lambda_lr * (Jc - cost_limit))``,
  where ``Jc`` is the mean summed cost of the episodes that ended in the rollout (an
  episode's cost is counted whole, also when it started in an earlier rollout); a
  rollout in which no episode ended leaves ``lambda`` as it is (:func:`lagrange_update`);
* the policy then optimises the penalised reward ``(r - lambda * c) / (1 + lambda)``
  with that (updated) ``lambda``: OmniSafe's PPOLag normalisation, which keeps the
  reward's scale bounded as ``lambda`` grows (:func:`penalised_reward`).

One critic, not two: the penalty is folded into the reward of the rollout buffer and
PPO's single value function learns the penalised return. OmniSafe keeps a second
(cost) critic and mixes the two advantages, ``(A_r - lambda A_c) / (1 + lambda)``,
which is the same objective; a cost critic would change the saved policy's network
(a second value head), and then a saved model would no longer be SB3's ``MlpPolicy``
that :mod:`agents.artifacts.sb3_zip` loads without unpickling and ``agents.evaluate``
acts with. Here the saved model *is* a PPO ``MlpPolicy`` plus three JSON numbers
(``cost_limit``, ``lambda_lr``, ``lagrange_multiplier``), so it evaluates like any PPO
model and a resumed run continues with the saved ``lambda``.

The penalty applies to the reward the agent sees: after ``VecNormalize``'s reward
scaling when a hyperparameter file turns it on (the project's files leave it off), so
``cost_limit`` stays in the units of the summed ``info['cost']``: on the trailer_env
scenes, steps in the singular band per episode.

Why on stable-baselines3 and not a safe-RL library: OmniSafe 0.5.0 (the latest, 2023)
needs safety-gymnasium, which pins gymnasium 0.28.1 (this project uses 1.x), pygame
2.1.0 (no wheel for Python 3.11, its source build fails) and pandas 2.0.3 (before
numpy 2); ``pip install -c constraints.txt omnisafe`` fails on this stack (torch 2.13
CPU). Its algorithms also train through its own environment interface, not SB3's, so
none of this project's batched env, callbacks, checkpoints or safe loading would carry
over. PPO-Lagrangian is a small change to PPO's rollout, so it is built here.

Logged each rollout (SB3's logger, ``logs/*/progress.csv``): ``lagrangian/lambda``,
``lagrangian/ep_cost_mean`` (when an episode ended), ``lagrangian/cost_limit`` and
``lagrangian/episodes``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.buffers import RolloutBuffer
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.type_aliases import MaybeCallback
from stable_baselines3.common.utils import obs_as_tensor
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper
from stable_baselines3.common.vec_env.base_vec_env import VecEnvObs, VecEnvStepReturn

from agents.algorithms.bounds import argument_problem

__all__ = ["PPOLagrangian", "info_column", "lagrange_update", "penalised_reward"]


def lagrange_update(multiplier: float, episode_cost: float, cost_limit: float, lr: float) -> float:
    """One projected gradient-ascent step of the multiplier on the constraint's violation.

    Returns ``max(0, multiplier + lr * (episode_cost - cost_limit))``: the multiplier rises
    while the mean episode cost is over the limit and falls, never below 0, while under.
    """
    return max(0.0, multiplier + lr * (episode_cost - cost_limit))


def penalised_reward(reward: np.ndarray, cost: np.ndarray, multiplier: float) -> np.ndarray:
    """``(reward - multiplier * cost) / (1 + multiplier)`` (OmniSafe's PPOLag scaling)."""
    return (reward - multiplier * cost) / (1.0 + multiplier)


def info_column(infos: Any, key: str) -> np.ndarray:
    """The value ``key`` of every environment's info, as a float array (N,).

    Reads a :class:`trailer_env.batch_infos.BatchInfos` column without building its
    dicts; any other sequence of dicts item by item.

    Raises:
        KeyError: If an info has no ``key`` (PPO-Lagrangian needs the env's cost).
    """
    column = getattr(infos, "column", None)
    try:
        if column is not None:
            return np.asarray(column(key), dtype=np.float64)
        return np.array([info[key] for info in infos], dtype=np.float64)
    except KeyError:
        raise KeyError(
            f"the environment's infos have no {key!r}: PPO-Lagrangian constrains info[{key!r}]"
        ) from None


def _number(name: str, value: object) -> float:
    """``value`` as a float within the bound of :data:`agents.algorithms.bounds.ARGUMENT_BOUNDS`
    (the one a hyperparameter file's or a search space's ``name`` is checked against)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(
        value, (int, float, np.floating, np.integer)
    ):
        raise TypeError(f"{name} must be a number, got {type(value).__name__}")
    number = float(value)
    problem = argument_problem("ppo_lag", name, number)
    if problem is not None:
        raise ValueError(problem)
    return number


class _CostRecorder(VecEnvWrapper):
    """The training env, recording one rollout's rewards and costs and its episodes' costs.

    Args:
        venv: The env the rollout steps.
        steps: Steps per environment in the rollout.
        running: Each environment's cost so far in its current episode (updated in place).
    """

    def __init__(self, venv: VecEnv, steps: int, running: np.ndarray) -> None:
        super().__init__(venv)
        self.rewards = np.zeros((steps, venv.num_envs), dtype=np.float32)
        self.costs = np.zeros((steps, venv.num_envs), dtype=np.float32)
        self.running = running
        self.finished: list[float] = []
        self._step = 0

    def reset(self) -> VecEnvObs:
        return self.venv.reset()

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, dones, infos = self.venv.step_wait()
        cost = info_column(infos, "cost")
        # A copy: SB3 adds the truncation bootstrap into this very array afterwards.
        self.rewards[self._step] = rewards
        self.costs[self._step] = cost
        self._step += 1
        self.running += cost
        if dones.any():
            rows = np.flatnonzero(dones)
            self.finished.extend(self.running[rows].tolist())
            self.running[rows] = 0.0
        return obs, rewards, dones, infos


class PPOLagrangian(PPO):
    """PPO with a Lagrange multiplier on the episode cost (see the module's docstring).

    Args:
        policy, env: As for :class:`stable_baselines3.PPO`.
        cost_limit: The constraint's bound on the expected summed ``info['cost']`` of an
            episode (>= 0; trailer_env: steps in the singular band per episode).
        lambda_lr: The multiplier's learning rate (> 0).
        lambda_init: The multiplier's starting value (>= 0).
        **kwargs: PPO's arguments.

    Raises:
        TypeError, ValueError: On a bad ``cost_limit``, ``lambda_lr`` or ``lambda_init``,
            before anything is built.
    """

    def __init__(
        self,
        policy: Any,
        env: Any,
        cost_limit: float = 5.0,
        lambda_lr: float = 0.01,
        lambda_init: float = 0.0,
        **kwargs: Any,
    ) -> None:
        self.cost_limit = _number("cost_limit", cost_limit)
        self.lambda_lr = _number("lambda_lr", lambda_lr)
        #: The multiplier lambda (saved with the model, so a resumed run continues it).
        self.lagrange_multiplier = _number("lambda_init", lambda_init)
        self._episode_costs: np.ndarray | None = None
        super().__init__(policy, env, **kwargs)

    def _excluded_save_params(self) -> list[str]:
        # Costs of unfinished episodes: a loaded model starts its episodes afresh.
        return [*super()._excluded_save_params(), "_episode_costs"]

    def _setup_learn(
        self,
        total_timesteps: int,
        callback: MaybeCallback = None,
        reset_num_timesteps: bool = True,
        tb_log_name: str = "run",
        progress_bar: bool = False,
    ) -> tuple[int, BaseCallback]:
        # SB3 resets the env here on a fresh start (or after a load): the episodes'
        # running costs start again with it.
        restart = reset_num_timesteps or self._last_obs is None
        result = super()._setup_learn(
            total_timesteps, callback, reset_num_timesteps, tb_log_name, progress_bar
        )
        if restart or self._episode_costs is None:
            self._episode_costs = np.zeros(self.n_envs)
        return result

    def collect_rollouts(
        self,
        env: VecEnv,
        callback: BaseCallback,
        rollout_buffer: RolloutBuffer,
        n_rollout_steps: int,
    ) -> bool:
        """PPO's rollout, then the multiplier's update and the penalised advantages."""
        if self._episode_costs is None or len(self._episode_costs) != env.num_envs:
            self._episode_costs = np.zeros(env.num_envs)
        recorder = _CostRecorder(env, n_rollout_steps, self._episode_costs)
        if not super().collect_rollouts(recorder, callback, rollout_buffer, n_rollout_steps):
            return False
        if recorder.finished:
            episode_cost = float(np.mean(recorder.finished))
            self.lagrange_multiplier = lagrange_update(
                self.lagrange_multiplier, episode_cost, self.cost_limit, self.lambda_lr
            )
            self.logger.record("lagrangian/ep_cost_mean", episode_cost)
        self.logger.record("lagrangian/lambda", self.lagrange_multiplier)
        self.logger.record("lagrangian/cost_limit", self.cost_limit)
        self.logger.record("lagrangian/episodes", len(recorder.finished))
        penalty = penalised_reward(recorder.rewards, recorder.costs, self.lagrange_multiplier)
        # The buffer holds the raw rewards plus SB3's bootstrap of truncated episodes;
        # only the raw part is replaced.
        rollout_buffer.rewards += penalty - recorder.rewards
        with torch.no_grad():
            last_values = self.policy.predict_values(
                obs_as_tensor(self._last_obs, self.device)  # type: ignore[arg-type]
            )
        rollout_buffer.compute_returns_and_advantage(
            last_values=last_values,
            dones=self._last_episode_starts,  # type: ignore[arg-type]
        )
        return True
