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
                                  6: 0.00151, 7: 0.000424, 8: 0.0000981}  # fmt: skip
    assert ReverseV1Core.perturbation_radius(0) == PERTURBATION_RADII[1]
    for n in (9, 12, 32):
        expected = 0.0000981 * (8 / n) ** PERTURBATION_EXPONENT
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


def _starts(scale: float | None) -> np.ndarray:
    """The starting states of 64 SB3 rows (n = 2) seeded 0..63, drawn after
    ``set_start_scale(scale)`` (None: not called)."""
    from trailer_env.sb3 import ConvoySB3VecEnv

    venv = ConvoySB3VecEnv(V1, num_envs=64, n_trailers=2)
    venv.seed(0)
    if scale is not None:
        venv.set_start_scale(scale)
    venv.reset()
    return venv.core.z.copy()


def test_start_scale_multiplies_the_perturbation_only() -> None:
    nominal = _starts(None)
    np.testing.assert_array_equal(_starts(1.0), nominal)  # scale 1: the scene's, to the bit
    half = _starts(0.5)
    np.testing.assert_array_equal(half[:, 0], nominal[:, 0])  # the speed: same draw
    np.testing.assert_allclose(half[:, 1:], 0.5 * nominal[:, 1:], rtol=1e-15, atol=0)
    radius = np.linalg.norm(half[:, 1:4], axis=1)
    np.testing.assert_allclose(radius, 0.5 * PERTURBATION_RADII[2], rtol=1e-12)


def test_start_scale_reaches_every_count_of_a_mixed_batch() -> None:
    from trailer_env.sb3 import ConvoySB3VecEnv

    venv = ConvoySB3VecEnv(V1, num_envs=8, n_trailers=[1, 3])
    venv.set_start_scale(0.25)
    assert [core.start_scale for core in venv.core.cores.values()] == [0.25, 0.25, 0.25]
    assert venv.core.start_scale == 0.25
    venv.seed(0)
    venv.reset()
    for n, core in venv.core.cores.items():
        rows = np.flatnonzero(venv.core.trailers == n)
        radius = np.linalg.norm(core.z[rows, 1 : 2 + n], axis=1)
        np.testing.assert_allclose(radius, 0.25 * PERTURBATION_RADII[n], rtol=1e-12)


@pytest.mark.parametrize(
    ("scale", "error", "words"),
    [
        (0.0, ValueError, r"start_scale must be in \(0, 2\]"),
        (-0.5, ValueError, "start_scale"),
        (2.5, ValueError, "start_scale"),
        (float("nan"), ValueError, "start_scale"),
        ("0.5", TypeError, "start_scale"),
    ],
)
def test_a_refused_start_scale_changes_nothing(scale: object, error: type, words: str) -> None:
    from trailer_env.sb3 import ConvoySB3VecEnv

    venv = ConvoySB3VecEnv(V1, num_envs=4, n_trailers=2)
    venv.set_start_scale(0.5)
    with pytest.raises(error, match=words):
        venv.set_start_scale(scale)  # type: ignore[arg-type]
    assert venv.core.start_scale == 0.5


def test_scenes_without_a_start_size_refuse_a_start_scale() -> None:
    from trailer_env.sb3 import ConvoySB3VecEnv

    for env_id in ("trailer_env/Reverse-v0", "trailer_env/Dock-v0", "trailer_env/Coast-v0"):
        venv = ConvoySB3VecEnv(env_id, num_envs=2, n_trailers=1)
        with pytest.raises(ValueError, match="no perturbation size to scale"):
            venv.set_start_scale(0.5)
        assert venv.core.start_scale == 1.0
