"""Seeded batched rollouts, their metrics, and the baselines' numbers on Reverse-v0."""

from __future__ import annotations

import numpy as np
import pytest

from agents.envs import env_settings
from agents.evaluation.metrics import rollout, summarize, wilson_interval
from agents.policies.baselines import make_baseline
from trailer_env.scenes import reverse as reverse_scene

REVERSE = "trailer_env/Reverse-v0"


def _baseline(name: str, n: int, seed: int = 0):  # type: ignore[no-untyped-def]
    return make_baseline(name, env_settings({"n_trailers": n}), REVERSE, seed)


def test_same_seed_same_results_different_seed_different() -> None:
    kwargs = {"n_trailers": 2}
    first = summarize(rollout(_baseline("random", 2, 7), REVERSE, 20, 100, kwargs))
    again = summarize(rollout(_baseline("random", 2, 7), REVERSE, 20, 100, kwargs))
    other = summarize(rollout(_baseline("random", 2, 7), REVERSE, 20, 200, kwargs))
    assert first == again
    assert first != other


def test_episode_bookkeeping_is_consistent() -> None:
    results = rollout(_baseline("zero", 2), REVERSE, 30, 1000, {"n_trailers": 2})
    assert np.array_equal(results.seeds, 1000 + np.arange(30))
    assert np.all((results.lengths >= 1) & (results.lengths <= 400))
    # Failing (folding, or stopping the reversal) ends the episode early; surviving
    # means running to the time limit.
    assert np.all(results.lengths[results.failed] < 400)
    assert np.all(results.lengths[~results.failed] == 400)
    assert np.all(results.failed >= results.jackknifed)  # a fold is a failure
    assert np.array_equal(results.success, ~results.failed)  # Reverse-v0's success
    assert results.margins.size == results.lengths.sum()
    assert np.all(results.band_steps <= results.lengths)
    assert np.all(results.safe <= ~results.failed)
    # A fold at |alpha_1| = pi/2 passes through the band: margin = |cos alpha_1| -> 0.
    assert np.all(results.min_margin >= 0.0) and np.all(results.min_margin <= 1.0)


def test_zero_folds_and_lqr_holds_most_two_trailer_convoys() -> None:
    kwargs = {"n_trailers": 2}
    zero = summarize(rollout(_baseline("zero", 2), REVERSE, 50, 1000, kwargs))
    lqr = summarize(rollout(_baseline("lqr", 2), REVERSE, 50, 1000, kwargs))
    assert zero["jackknife_rate"] == 1.0 and zero["safe_rate"] == 0.0
    assert lqr["jackknife_rate"] < 0.45 and lqr["safe_rate"] > 0.5
    assert lqr["mean_return"] > 5 * zero["mean_return"]


def test_one_trailer_has_no_singular_band() -> None:
    results = rollout(_baseline("zero", 1), REVERSE, 10, 0, {"n_trailers": 1})
    assert np.all(results.margins == 1.0) and np.all(results.band_steps == 0)
    assert np.array_equal(results.safe, ~results.failed)


def test_stopping_the_reversal_is_a_failure_not_safe(monkeypatch: pytest.MonkeyPatch) -> None:
    # Start almost at rest and slam the mass against its motion: the convoy stops
    # reversing without folding. Before the env ended such episodes, braking counted
    # as safe; now it must count as a failure, neither safe nor successful.
    monkeypatch.setattr(reverse_scene, "SPEED_RANGE", (0.02, 0.05))

    def against_the_mass(obs: np.ndarray) -> np.ndarray:
        return -np.sign(obs[:, -2:-1] + 1e-3).astype(np.float32)

    results = rollout(against_the_mass, REVERSE, 20, 1000, {"n_trailers": 2})
    stopped = results.failed & ~results.jackknifed
    assert stopped.sum() >= 10
    assert not np.any(results.safe | results.success)
    assert summarize(results)["failure_rate"] == pytest.approx(results.failed.mean())


def test_wilson_interval() -> None:
    low, high = wilson_interval(95, 100)
    assert low == pytest.approx(0.888, abs=1e-3) and high == pytest.approx(0.978, abs=1e-3)
    assert wilson_interval(0, 0) == (0.0, 1.0)
    assert wilson_interval(0, 10)[0] == 0.0 and wilson_interval(10, 10)[1] == 1.0


def test_rollout_rejects_no_episodes() -> None:
    with pytest.raises(ValueError, match=r"episodes must be in 1\.\.100000"):
        rollout(_baseline("zero", 2), REVERSE, 0, 0, {"n_trailers": 2})
