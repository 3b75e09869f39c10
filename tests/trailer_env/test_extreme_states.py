"""Extreme states are never silently wrong: folds between control instants, the accuracy
warning, and the retry of a diverged step (issue 13)."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numba
import numpy as np
import pytest

from tests.trailer_env.helpers import make
from trailer_env.core import ConvoyCore
from trailer_env.fidelity import AccuracyWarning
from trailer_env.scenes import CoastCore, ReverseCore
from trailer_env.settings import settings_from_kwargs


def test_a_fold_between_control_instants_is_detected(rng: np.random.Generator) -> None:
    """At u = -1000 a hitch angle turns by 2 pi within one step; the fold must be seen."""
    env = make("Coast", n_trailers=2)
    for seed in range(10):
        env.reset(seed=seed)
        env.unwrapped.set_state(np.array([-1000.0, 0.0, 0.01, -0.01]))  # type: ignore[attr-defined]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", AccuracyWarning)
            _, reward, terminated, _, info = env.step(rng.uniform(-1.0, 1.0, 1).astype(np.float32))
        assert info["jackknifed"] and terminated
        assert reward <= -20.0 + 1.0  # the fold penalty (plus at most the potential change)


@pytest.mark.parametrize("speed", [-1000.0, 1e8])
def test_a_step_over_the_tolerance_warns_once_and_flags_its_rows(speed: float) -> None:
    core = CoastCore(settings_from_kwargs(n_trailers=2), 3)
    core.reset_rows(np.arange(3), [np.random.default_rng(i) for i in range(3)])
    core.z[1, :4] = [speed, 0.0, 0.01, -0.01]
    core.refresh()
    start_energy = core.energy[1]
    with pytest.warns(AccuracyWarning, match="max_substeps"):
        core.step(np.zeros((3, 1)))
    np.testing.assert_array_equal(core.accuracy_exceeded, [False, True, False])
    assert abs(core.energy[1] / start_energy - 1.0) > 0.05  # why it warns: the error is real
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)  # once per core
        core.step(np.zeros((3, 1)))


def test_scene_speeds_stay_within_the_tolerance(rng: np.random.Generator) -> None:
    core = ReverseCore(settings_from_kwargs(n_trailers=3), 64)
    core.reset_rows(np.arange(64), [np.random.default_rng(i) for i in range(64)])
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)
        for _ in range(20):
            core.step(rng.uniform(-1.0, 1.0, (64, 1)))
            assert not core.accuracy_exceeded.any()


def _fail_rows(core: ConvoyCore, monkeypatch: pytest.MonkeyPatch, row: int, times: int) -> None:
    """Make the next ``times`` integrations of ``row`` (first try, then retries) non-finite."""
    real = core._physics_step
    left = [times]

    def physics_step(
        action: np.ndarray, rows: np.ndarray, prepare: bool, outcome: bool = True
    ) -> tuple:
        if left[0] > 0 and row in rows:
            # As a real divergence: the scene kernel leaves the results to the core.
            result = real(action, rows, prepare, outcome=False)
            left[0] -= 1
            core.z[row] = np.nan
            core.step_outputs.nonfinite[row] = True
            return result[0], 1, result[2]
        return real(action, rows, prepare, outcome)

    monkeypatch.setattr(core, "_physics_step", physics_step)


@pytest.mark.parametrize("fidelity", [2, "auto"])
def test_a_diverged_step_is_retried_on_its_rows_only(
    monkeypatch: pytest.MonkeyPatch, rng: np.random.Generator, fidelity: object
) -> None:
    settings = settings_from_kwargs(n_trailers=2, fidelity=fidelity)
    seeds = [np.random.default_rng(i) for i in range(6)]
    actions = rng.uniform(-1.0, 1.0, (6, 1))
    reference = CoastCore(settings, 6)
    reference.reset_rows(np.arange(6), [np.random.default_rng(i) for i in range(6)])
    reference.step(actions)
    used = reference.substeps.copy()
    core = CoastCore(settings, 6)
    core.reset_rows(np.arange(6), seeds)
    _fail_rows(core, monkeypatch, 4, 1)
    core.step(actions)
    assert np.all(np.isfinite(core.z))
    others = [0, 1, 2, 3, 5]
    np.testing.assert_array_equal(core.z[others], reference.z[others])
    np.testing.assert_array_equal(core.obs[others], reference.obs[others])
    # The failed row was redone with 8 times the substeps: as a finer fixed-step run.
    finer = CoastCore(settings_from_kwargs(n_trailers=2, fidelity=int(8 * used[4])), 1)
    finer.reset_rows(np.arange(1), [np.random.default_rng(4)])
    finer.step(actions[4:5])
    np.testing.assert_array_equal(core.z[4], finer.z[0])
    # The outcome ran once, on the final state of every row.
    np.testing.assert_array_equal(core.reward[others], reference.reward[others])
    np.testing.assert_array_equal(core.terminated[others], reference.terminated[others])
    assert core.reward[4] == finer.reward[0] and core.success[4] == finer.success[0]
    np.testing.assert_array_equal(
        core.previous_potential[others], reference.previous_potential[others]
    )
    if fidelity == 2:
        np.testing.assert_array_equal(core.substeps, [2] * 6)  # restored
    # The next step is again the reference's, row for row (replays are intact).
    reference.z[4], reference.act[4] = core.z[4], core.act[4]
    reference.refresh()
    core.step(actions)
    reference.step(actions)
    np.testing.assert_array_equal(core.z, reference.z)


def test_a_step_that_diverges_twice_leaves_the_state_unchanged(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    core = CoastCore(settings_from_kwargs(n_trailers=2, fidelity=1), 3)
    core.reset_rows(np.arange(3), [np.random.default_rng(i) for i in range(3)])
    _fail_rows(core, monkeypatch, 0, 2)
    before = core.z.copy()
    core.reward[:] = [1.5, 2.5, 3.5]  # a previous step's results, kept by the refusal
    core.terminated[:] = [False, True, False]
    with pytest.raises(FloatingPointError, match="previous step"):
        core.step(np.zeros((3, 1)))
    np.testing.assert_array_equal(core.z, before)
    np.testing.assert_array_equal(core.substeps, [1, 1, 1])
    np.testing.assert_array_equal(core.reward, [1.5, 2.5, 3.5])
    np.testing.assert_array_equal(core.terminated, [False, True, False])


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs two numba threads")
def test_vector_env_results_do_not_depend_on_the_thread_count(rng: np.random.Generator) -> None:
    from trailer_env.kernels import PARALLEL_MIN_ROWS

    count = PARALLEL_MIN_ROWS + 70
    actions = rng.uniform(-1.0, 1.0, (12, count, 1)).astype(np.float32)
    before = numba.get_num_threads()
    runs = []
    try:
        for threads in (1, 2):
            numba.set_num_threads(threads)
            envs = gym.make_vec(
                "trailer_env/Reverse-v0",
                num_envs=count,
                vectorization_mode="vector_entry_point",
                n_trailers=3,
            )
            observations, rewards = [envs.reset(seed=3)[0]], []
            for action in actions:
                obs, reward, *_ = envs.step(action)
                observations.append(obs)
                rewards.append(reward)
            runs.append((np.array(observations), np.array(rewards)))
    finally:
        numba.set_num_threads(before)
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][1], runs[1][1])
