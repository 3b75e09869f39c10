"""Potential-based shaping (trailer_env.shaping, wrappers.PotentialShaping,
sb3.PotentialShapingVecEnv): it adds gamma Phi(s') - Phi(s) and changes nothing else."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import trailer_env  # noqa: F401
from trailer_env.controllers import DESIGN_SPEEDS, LQRController, regulator
from trailer_env.sb3 import ConvoySB3VecEnv, PotentialShapingVecEnv
from trailer_env.shaping import LQR_REFERENCE, LQRPotential, make_potential
from trailer_env.wrappers import PotentialShaping

ENV_ID = "trailer_env/Reverse-v1"


def _episode(env: gym.Env, seed: int, action: float) -> tuple[list[float], list, list]:
    """Rewards, infos and (terminated, truncated) flags of one constant-action episode."""
    env.reset(seed=seed)
    rewards, infos, flags = [], [], []
    while True:
        _, reward, terminated, truncated, info = env.step(np.array([action], np.float32))
        rewards.append(float(reward))
        infos.append(info)
        flags.append((terminated, truncated))
        if terminated or truncated:
            return rewards, infos, flags


def test_cost_to_go_is_the_riccati_quadratic_form_at_a_design_speed():
    env = gym.make(ENV_ID, n_trailers=2)
    obs, _ = env.reset(seed=4)
    controller = LQRController(env.unwrapped.settings)
    speed = -DESIGN_SPEEDS[4]  # 1.0 m/s reversing: no interpolation
    obs = obs.copy()
    obs[0] = speed
    _, riccati = regulator(env.unwrapped.settings, speed)
    state = controller.regulator_state(obs)[0]
    assert controller.cost_to_go(obs)[0] == pytest.approx(state @ riccati @ state, rel=1e-12)
    assert np.all(np.linalg.eigvalsh(riccati) > 0)  # a cost-to-go: positive definite
    potential = LQRPotential(env.unwrapped.settings)
    expected = -np.log1p(state @ riccati @ state / LQR_REFERENCE)
    assert potential(obs)[0] == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("n", [1, 3])
def test_shaping_telescopes_and_leaves_the_scene_unchanged(n):
    plain = gym.make(ENV_ID, n_trailers=n)
    shaped = PotentialShaping(gym.make(ENV_ID, n_trailers=n), potential="lqr", gamma=1.0)
    rewards, infos, flags = _episode(plain, 11, 0.0)
    shaped_rewards, shaped_infos, shaped_flags = _episode(shaped, 11, 0.0)
    assert flags == shaped_flags and flags[-1] == (True, False)  # the zero action folds
    assert [info["unshaped_reward"] for info in shaped_infos] == rewards  # bit for bit
    assert [info["is_success"] for info in shaped_infos] == [i["is_success"] for i in infos]
    first_obs, _ = shaped.reset(seed=11)
    start_potential = shaped.potential(first_obs)[0]
    assert start_potential < 0
    # gamma = 1 and Phi = 0 at the end: the added terms sum to -Phi(s_0), whatever happened.
    added = sum(shaped_rewards) - sum(rewards)
    assert added == pytest.approx(-start_potential, abs=1e-9)
    # Before the fold the terms are the potential's steps: a diverging convoy loses reward.
    assert shaped_rewards[-2] < rewards[-2]


def test_the_batch_wrapper_matches_the_single_env_wrapper_and_records_unshaped_returns():
    gamma = 0.999
    venv = PotentialShapingVecEnv(ConvoySB3VecEnv(ENV_ID, 3, n_trailers=2), gamma=gamma)
    venv.seed(20)
    venv.reset()
    singles = [PotentialShaping(gym.make(ENV_ID, n_trailers=2), gamma=gamma) for _ in range(3)]
    for i, env in enumerate(singles):
        env.reset(seed=20 + i)
    ends = 0
    episode_returns = np.zeros(3)
    for _ in range(120):
        action = np.full((3, 1), 0.3, np.float32)
        _, rewards, dones, infos = venv.step(action)
        for i, env in enumerate(singles):
            _, reward, terminated, truncated, info = env.step(action[i])
            assert rewards[i] == pytest.approx(reward, abs=2e-6)
            assert venv.unshaped_rewards[i] == np.float32(info["unshaped_reward"])
            episode_returns[i] += np.float32(info["unshaped_reward"])
            assert dones[i] == (terminated or truncated)
            if dones[i]:
                ends += 1
                # The adapter's statistics are the scene's own (unshaped) return.
                assert infos[i]["episode"]["r"] == pytest.approx(episode_returns[i], rel=1e-6)
                episode_returns[i] = 0.0
                env.reset(seed=None)
    assert ends >= 3  # every env ended at least once (a constant push folds the convoy)


def test_a_time_limit_cut_bootstraps_the_potential_of_the_state_reached():
    venv = PotentialShapingVecEnv(
        ConvoySB3VecEnv(ENV_ID, 1, max_episode_steps=5, n_trailers=1), gamma=0.9
    )
    venv.seed(3)
    obs = venv.reset()
    before = venv.potential(obs)[0]
    for _ in range(5):
        obs, rewards, dones, infos = venv.step(np.zeros((1, 1), np.float32))
        if not dones[0]:
            before_next = venv.potential(obs)[0]
            expected = venv.unshaped_rewards[0] + 0.9 * before_next - before
            before = before_next
    assert dones[0] and infos[0]["TimeLimit.truncated"]
    reached = venv.potential(infos[0]["terminal_observation"])[0]
    expected = np.float64(venv.unshaped_rewards[0]) + 0.9 * reached - before
    assert rewards[0] == pytest.approx(expected, rel=1e-6)


def test_bad_shaping_arguments_are_refused_naming_them():
    env = gym.make(ENV_ID, n_trailers=1)
    with pytest.raises(ValueError, match="unknown potential 'energy'"):
        PotentialShaping(env, potential="energy")
    with pytest.raises(ValueError, match="gamma"):
        PotentialShaping(env, gamma=1.5)
    with pytest.raises(TypeError, match="gamma"):
        PotentialShaping(env, gamma="0.9")
    with pytest.raises(TypeError, match="unexpected keyword"):
        PotentialShaping(env, weight=2.0)
    with pytest.raises(ValueError, match="scale"):
        make_potential("lqr", env.unwrapped.settings, scale=-1.0)
    with pytest.raises(TypeError, match="one environment"):
        PotentialShaping(gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point"))
    with pytest.raises(ValueError, match="one count of trailers"):
        PotentialShapingVecEnv(ConvoySB3VecEnv(ENV_ID, 4, n_trailers=(1, 2)))
    with pytest.raises(ValueError, match="flat observation"):
        PotentialShaping(gym.make(ENV_ID, n_trailers=1, observation="trailers"))
    with pytest.raises(ValueError, match="flat observation"):
        PotentialShapingVecEnv(ConvoySB3VecEnv(ENV_ID, 2, n_trailers=1, observation="trailers"))
    with pytest.raises(TypeError, match="ConvoySB3VecEnv"):
        PotentialShapingVecEnv(env)  # type: ignore[arg-type]
