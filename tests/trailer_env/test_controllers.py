"""The LQR controller has real authority where the zero action folds the convoy."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from tests.trailer_env.helpers import make
from trailer_env.controllers import LQRController


def _jackknife_rate(policy: str, seeds: int = 24, n: int = 2) -> tuple[float, float]:
    envs = gym.make_vec(
        "trailer_env/Reverse-v0",
        num_envs=seeds,
        vectorization_mode="vector_entry_point",
        n_trailers=n,
    )
    controller = LQRController.from_env(envs)
    obs, _ = envs.reset(seed=100)
    alive = np.ones(seeds, dtype=bool)
    folded = np.zeros(seeds, dtype=bool)
    lifetime = np.zeros(seeds)
    for _ in range(400):
        actions = controller(obs) if policy == "lqr" else np.zeros((seeds, 1), dtype=np.float32)
        obs, _, terminated, truncated, infos = envs.step(actions)
        folded |= alive & infos["jackknifed"]
        lifetime += alive
        alive &= ~(terminated | truncated)
        if not alive.any():
            break
    return float(folded.mean()), float(lifetime.mean())


def test_lqr_keeps_a_reversing_convoy_from_folding() -> None:
    zero_rate, zero_life = _jackknife_rate("zero")
    lqr_rate, lqr_life = _jackknife_rate("lqr")
    assert zero_rate >= 0.9 and zero_life < 100  # the unstable node folds within seconds
    assert lqr_rate <= 0.5 and lqr_life > 2 * zero_life


def test_lqr_controller_shapes_and_modes() -> None:
    env = make("Reverse", n_trailers=2)
    obs, _ = env.reset(seed=0)
    policy = LQRController.from_env(env)
    action = policy(obs)
    assert action.shape == (1,) and action.dtype == np.float32 and env.action_space.contains(action)
    batch = policy(np.stack([obs, obs]))
    assert batch.shape == (2, 1)
    for mode in ("accel", "planar"):
        env = make("Dock", n_trailers=1, action_mode=mode)
        obs, _ = env.reset(seed=0)
        action = LQRController.from_env(env)(obs)
        assert env.action_space.contains(action)


def test_regulator_gains_are_stabilising() -> None:
    from trailer_env.controllers import linearise, regulator_gain

    settings = make("Reverse", n_trailers=3).unwrapped.settings
    for speed in (-1.0, 1.0):
        a_matrix, b_matrix = linearise(settings, speed)
        closed = a_matrix - b_matrix @ regulator_gain(settings, speed)[None, :]
        assert np.max(np.linalg.eigvals(closed).real) < 0.0
    open_loop = np.linalg.eigvals(linearise(settings, -1.0)[0]).real
    assert np.max(open_loop) > 0.5  # reversing is unstable


def test_heading_baseline_succeeds_where_the_zero_action_cannot() -> None:
    from trailer_env.controllers import heading_policy

    count = 16
    envs = gym.make_vec(
        "trailer_env/Heading-v0", num_envs=count, vectorization_mode="vector_entry_point"
    )
    results = {}
    for name in ("zero", "baseline"):
        obs, _ = envs.reset(seed=0)
        alive = np.ones(count, dtype=bool)
        succeeded = np.zeros(count, dtype=bool)
        for _ in range(300):
            actions = (
                heading_policy(obs) if name == "baseline" else np.zeros((count, 1), np.float32)
            )
            obs, _, terminated, truncated, infos = envs.step(actions)
            succeeded |= alive & infos["is_success"]
            alive &= ~(terminated | truncated)
        results[name] = succeeded.mean()
    assert results["zero"] == 0.0
    assert results["baseline"] >= 0.6
