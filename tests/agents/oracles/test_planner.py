"""The sampling planner: it reproduces the LQR when it cannot search, and rescues a fold."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import trailer_env  # noqa: F401  (registers the ids)
from agents.oracles.mpc_policy import state_from_observation
from agents.oracles.planner import PlannerConfig, SamplingPlanner, plan_episodes
from agents.policies.baselines import make_baseline
from trailer_env.controllers import LQRController
from trailer_env.scenes.reverse import ReverseCore
from trailer_env.settings import settings_from_kwargs
from trailer_env.vector import seed_generators

REVERSE = "trailer_env/Reverse-v0"
#: A Reverse-v0 start (n = 2) that the LQR folds and the planner keeps safe.
RESCUED_SEED = 1005


def reverse_core(n: int, seeds: list[int]) -> ReverseCore:
    core = ReverseCore(settings_from_kwargs(n_trailers=n), len(seeds))
    core.reset_rows(np.arange(len(seeds)), seed_generators(seeds, len(seeds), None))
    return core


def test_planner_without_spread_plays_the_lqr() -> None:
    settings = settings_from_kwargs(n_trailers=2)
    core = reverse_core(2, [1000, 1001, 1002])
    config = PlannerConfig(
        samples=2, elites=1, horizon=3, tail=0, iterations=1, noise=1e-12, min_noise=0.0
    )
    planner = SamplingPlanner(ReverseCore, settings, 3, config)
    lqr = LQRController(settings)
    for _ in range(5):
        planned = planner.plan(core.z, core.act)
        # The LQR reads the float32 observation, the planner the exact state.
        np.testing.assert_allclose(planned, lqr(core.obs), atol=1e-6)
        core.step(planned)


def test_state_from_observation_round_trips() -> None:
    settings = settings_from_kwargs(n_trailers=3)
    core = reverse_core(3, [7, 8])
    core.act[:, 1] = [0.1, -0.2]
    core.act[:, 3] = [0.3, 0.0]
    core.refresh()
    z, act = state_from_observation(core.obs, settings)
    np.testing.assert_allclose(z, core.z, atol=1e-6)
    np.testing.assert_allclose(act[:, [1, 3]], core.act[:, [1, 3]], atol=1e-6)


def test_bad_config_raises() -> None:
    with pytest.raises(ValueError, match="elites"):
        PlannerConfig(samples=4, elites=4)
    with pytest.raises(ValueError, match="horizon"):
        PlannerConfig(horizon=0)
    with pytest.raises(ValueError, match="planar"):
        SamplingPlanner(ReverseCore, settings_from_kwargs(action_mode="planar"), 1)


def test_mpc_is_a_baseline() -> None:
    settings = settings_from_kwargs(n_trailers=1)
    policy = make_baseline("mpc", settings, REVERSE)
    env = gym.make(REVERSE, n_trailers=1)
    obs, _ = env.reset(seed=3)
    action = policy(obs[None])
    assert action.shape == (1, 1)
    assert action.dtype == np.float32
    assert -1.0 <= float(action[0, 0]) <= 1.0


@pytest.mark.slow
def test_planner_rescues_a_start_the_lqr_folds() -> None:
    env = gym.make(REVERSE, n_trailers=2)
    obs, _ = env.reset(seed=RESCUED_SEED)
    lqr = make_baseline("lqr", settings_from_kwargs(n_trailers=2), REVERSE)
    folded = False
    for _ in range(400):
        obs, _, terminated, truncated, info = env.step(lqr(obs[None])[0])
        if terminated or truncated:
            folded = bool(info["jackknifed"])
            break
    assert folded
    core = reverse_core(2, [RESCUED_SEED])
    planner = SamplingPlanner(ReverseCore, core.settings, 1)
    result = plan_episodes(core, planner, 400)
    assert result.safe[0]
    assert result.lengths[0] == 400
