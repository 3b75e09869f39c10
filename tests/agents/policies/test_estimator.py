"""lqr-estimated: the LQR designed for parameters estimated online from the motion.

Measured: from the nominal start the windowed Gauss-Newton fit reaches every drawn factor
to about 1 % within 4-8 steps of Reverse-v1 (n = 1..3) and to about 1e-4 within 20-50,
and holds it; the tests allow 5e-3 (RECOVERY) at step 150.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from agents.policies.baselines import AdaptiveLQRPolicy, make_baseline
from agents.policies.estimator import ESTIMABLE, EstimatingLQRPolicy, ParameterEstimator
from agents.policies.registry import load_policy
from trailer_env.benchmark import rollout
from trailer_env.registry import core_class_of

REVERSE = "trailer_env/Reverse-v1"
#: Largest relative error of a recovered parameter after STEPS steps.
RECOVERY = 5e-3
STEPS = 150


def _vector(n: int, rows: int, **kwargs: Any) -> gym.vector.VectorEnv:
    return gym.make_vec(
        REVERSE,
        num_envs=rows,
        vectorization_mode="vector_entry_point",
        n_trailers=n,
        randomize="mismatch20",
        **kwargs,
    )


def _relative_errors(policy: EstimatingLQRPolicy, truth: np.ndarray) -> np.ndarray:
    """|estimate / truth - 1| of the estimated parameters (B, P)."""
    columns = policy.estimator.columns
    return np.abs(policy.estimator.values[:, columns] / truth[:, columns] - 1.0)


@pytest.mark.parametrize("n", [1, 3])
def test_recovers_the_drawn_parameters(n: int) -> None:
    """Each of M, J0, a, l, mu within RECOVERY of the episode's draw after 150 steps of
    its own control (or at the end of a shorter episode, none shorter than 30 steps),
    from observations and its actions only."""
    envs = _vector(n, 3)
    native = envs.unwrapped
    obs, _ = envs.reset(seed=1000)
    policy = make_baseline("lqr-estimated", native.settings, REVERSE)
    assert isinstance(policy, EstimatingLQRPolicy)
    assert policy.estimator.names == ESTIMABLE
    truth = native.core.param_values.copy()
    columns = policy.estimator.columns
    start = np.abs(policy.estimator.nominal[columns] / truth[:, columns] - 1.0)
    final = np.zeros_like(truth)
    ended = np.zeros(3, dtype=bool)
    lengths = np.zeros(3, dtype=np.int64)
    for _ in range(STEPS):
        actions = policy(obs)
        final[~ended] = policy.estimator.values[~ended]
        obs, _, terminated, truncated, _ = envs.step(actions)
        lengths[~ended] += 1
        ended |= terminated | truncated
    errors = np.abs(final[:, columns] / truth[:, columns] - 1.0)
    assert errors.shape == (3, len(ESTIMABLE)) and lengths.min() >= 30
    assert errors.max() < RECOVERY, errors
    assert start.max() > 0.1  # the draws were away from nominal


def test_a_new_episode_restarts_the_estimate() -> None:
    """Another start (new draws) is seen in the motion: the row restarts from nominal and
    converges to the new draws."""
    envs = _vector(2, 2)
    native = envs.unwrapped
    obs, _ = envs.reset(seed=20)
    policy = make_baseline("lqr-estimated", native.settings, REVERSE)
    assert isinstance(policy, EstimatingLQRPolicy)
    for _ in range(30):
        obs, *_ = envs.step(policy(obs))
    first = native.core.param_values.copy()
    obs, _ = envs.reset(seed=40)
    second = native.core.param_values.copy()
    assert np.abs(second / first - 1.0).max() > 0.05
    policy(obs)
    assert policy.estimator.restarted.all()
    np.testing.assert_array_equal(policy.estimator.factors, 1.0)
    for _ in range(40):
        obs, *_ = envs.step(policy(obs))
    assert _relative_errors(policy, second).max() < RECOVERY


def test_without_randomisation_it_is_the_lqr() -> None:
    envs = gym.make_vec(REVERSE, num_envs=3, vectorization_mode="vector_entry_point", n_trailers=2)
    obs, _ = envs.reset(seed=1)
    settings = envs.unwrapped.settings
    estimated = make_baseline("lqr-estimated", settings, REVERSE)
    lqr = make_baseline("lqr", settings, REVERSE)
    for _ in range(3):
        actions = estimated(obs)
        np.testing.assert_array_equal(actions, lqr(obs))
        obs, *_ = envs.step(actions)
    assert isinstance(estimated, EstimatingLQRPolicy)
    assert estimated.estimator.names == () and estimated.estimator.factors.shape == (3, 0)


def test_runs_through_the_loader_like_lqr_adaptive() -> None:
    """Two episodes through agents.evaluate's loader: the same outcomes as the privileged
    regulator on these starts (measured: the same safe flags on all of seeds 1000-1049 at
    n = 2)."""
    kwargs = {"n_trailers": 2, "randomize": "mismatch20"}
    policy = load_policy("lqr-estimated", REVERSE, kwargs)
    assert not hasattr(policy, "observe")  # reads observations only, not the core
    results = rollout(policy, REVERSE, 2, 1000, kwargs)
    adaptive = rollout(load_policy("lqr-adaptive", REVERSE, kwargs), REVERSE, 2, 1000, kwargs)
    assert results.lengths.tolist() == adaptive.lengths.tolist()
    np.testing.assert_array_equal(results.safe, adaptive.safe)
    assert results.lengths.min() > 100


def test_bad_settings_are_refused() -> None:
    envs = _vector(1, 1)
    settings = envs.unwrapped.settings
    core = core_class_of(REVERSE)
    design = AdaptiveLQRPolicy(settings).controller
    with pytest.raises(ValueError, match="window"):
        ParameterEstimator(settings, core, window=0)
    with pytest.raises(TypeError, match="window must be an int"):
        ParameterEstimator(settings, core, window=2.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="damping"):
        ParameterEstimator(settings, core, damping=-1.0)
    with pytest.raises(ValueError, match="reset_tolerance"):
        ParameterEstimator(settings, core, reset_tolerance=0.0)
    with pytest.raises(ValueError, match="redesign_tolerance"):
        EstimatingLQRPolicy(settings, core, design, redesign_tolerance=-0.1)
