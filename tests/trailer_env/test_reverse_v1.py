"""Reverse-v1: its start distribution, its minimum reversing speed, and that v0 is unchanged."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils import seeding

import trailer_env
from trailer_env.scenes.reverse import ReverseCore
from trailer_env.scenes.reverse_v1 import (
    MIN_REVERSE_SPEED,
    PERTURBATION_EXPONENT,
    PERTURBATION_RADII,
    SPEED_RANGE,
    ReverseV1Core,
)

V1 = "trailer_env/Reverse-v1"


def test_registered_next_to_v0() -> None:
    assert V1 in trailer_env.ENVIRONMENTS
    assert "trailer_env/Reverse-v0" in trailer_env.ENVIRONMENTS
    assert ReverseV1Core.version == 1 and ReverseCore.version == 0
    assert "mpc" not in ReverseV1Core.baselines  # a planner: the agents' record says so


@pytest.mark.parametrize("n", [1, 2, 3])
def test_start_distribution(n: int) -> None:
    count = 2000
    envs = gym.make_vec(V1, num_envs=count, vectorization_mode="vector_entry_point", n_trailers=n)
    envs.reset(seed=0)
    z = envs.unwrapped.core.z
    speed = -z[:, 0]
    assert speed.min() >= SPEED_RANGE[0] and speed.max() <= SPEED_RANGE[1]
    assert speed.min() < SPEED_RANGE[0] + 0.01 and speed.max() > SPEED_RANGE[1] - 0.01
    # (omega, alpha_1..alpha_n) lies on the sphere of the radius sized for n ...
    radius = PERTURBATION_RADII[n]
    assert ReverseV1Core.perturbation_radius(n) == radius
    perturbation = z[:, 1 : 2 + n]
    np.testing.assert_allclose(np.linalg.norm(perturbation, axis=1), radius, rtol=1e-12)
    # ... uniformly: zero mean, each component's mean square radius^2 / (n + 1).
    sigma = radius / np.sqrt(n + 1)
    np.testing.assert_allclose(perturbation.mean(axis=0), 0.0, atol=5 * sigma / np.sqrt(count))
    np.testing.assert_allclose(np.mean(perturbation**2, axis=0), sigma**2, rtol=0.15)
    np.testing.assert_array_equal(envs.unwrapped.core.act[:, 1], 0.0)  # the mass centred
    envs.close()


def test_radius_beyond_the_sized_counts() -> None:
    assert PERTURBATION_RADII == {1: 0.064, 2: 0.0365, 3: 0.0229, 4: 0.0122, 5: 0.00443,
                                  6: 0.00151}  # fmt: skip
    assert ReverseV1Core.perturbation_radius(0) == PERTURBATION_RADII[1]
    for n in (7, 8, 32):
        expected = 0.00151 * (6 / n) ** PERTURBATION_EXPONENT
        assert ReverseV1Core.perturbation_radius(n) == pytest.approx(expected, rel=1e-15)


def test_v0_start_distribution_is_unchanged() -> None:
    env = gym.make("trailer_env/Reverse-v0", n_trailers=2)
    env.reset(seed=1000)
    rng = seeding.np_random(1000)[0]  # v0's draw: U(0.8, 1.2), then omega, then the angles
    expected = [-rng.uniform(0.8, 1.2), rng.uniform(-0.05, 0.05), *rng.uniform(-0.05, 0.05, 2)]
    np.testing.assert_array_equal(env.unwrapped.core.z[0], expected)


def test_slowing_below_the_minimum_speed_fails() -> None:
    env = gym.make(V1, n_trailers=1)
    env.reset(seed=1)
    env.unwrapped.set_state([-MIN_REVERSE_SPEED + 0.01, 0.0, 0.0])
    _, _, terminated, _, info = env.step(np.zeros(1, np.float32))
    assert terminated and not info["is_success"] and not info["jackknifed"]
    env.unwrapped.set_state([-MIN_REVERSE_SPEED - 0.05, 0.0, 0.0])
    _, _, terminated, _, info = env.step(np.zeros(1, np.float32))
    assert not terminated and info["is_success"]


def test_zero_action_folds_every_episode() -> None:
    envs = gym.make_vec(V1, num_envs=50, vectorization_mode="vector_entry_point", n_trailers=2)
    envs.reset(seed=2000)
    folded = np.zeros(50, dtype=bool)
    running = np.ones(50, dtype=bool)
    for _ in range(400):
        _, _, terminated, _, info = envs.step(np.zeros((50, 1), np.float32))
        folded |= running & terminated & info["jackknifed"]
        running &= ~terminated
        if not running.any():
            break
    assert folded.all()
