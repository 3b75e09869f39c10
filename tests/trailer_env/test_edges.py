"""Issue 21, the environment side: nothing silent, nothing destroyed, nothing unbounded.

Every refusal is checked to change nothing: the state, the observation and the
generator's state are compared before and after.
"""

from __future__ import annotations

import copy
import pickle
import time
import warnings
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import trailer_env
from trailer_env.kernels import OBS_BOUND
from trailer_env.registry import core_class_of
from trailer_env.substeps import MAX_STEP_WORK
from trailer_env.vector import MAX_RENDER_ENVS, ConvoyVectorEnv


def make_vec(env_id: str, num_envs: int, **kwargs: Any) -> Any:
    return gym.make_vec(
        env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs
    )


def snapshot(env: Any) -> tuple:
    """Everything a refusal must leave alone: state, mass, observation, generator(s)."""
    core = env.unwrapped.core if hasattr(env, "unwrapped") else env.core
    generators = getattr(env.unwrapped, "_generators", None) if hasattr(env, "unwrapped") else None
    if generators is None and hasattr(env, "unwrapped"):
        generators = [env.unwrapped.np_random]
    if generators is None:
        generators = getattr(env, "_generators", None) or []
    return (
        core.z.copy(),
        core.act[:, :4].copy(),
        core.obs.copy(),
        core.energy.copy(),
        repr([rng.bit_generator.state for rng in generators]),
    )


def assert_unchanged(before: tuple, after: tuple) -> None:
    for first, second in zip(before[:4], after[:4], strict=True):
        np.testing.assert_array_equal(first, second)
    assert before[4] == after[4]


# ---------------------------------------------------------------- 1. divergence
def test_a_diverging_step_raises_naming_the_row_and_changes_nothing() -> None:
    env = gym.make("trailer_env/Reverse-v0", fidelity=1)
    env.reset(seed=0, options={"state": [20000.0, 0.0, 0.1, -0.1]})
    before = snapshot(env)
    with pytest.raises(FloatingPointError, match=r"diverged in environment\(s\) \[0\].*non-finite"):
        env.step(np.zeros(1))
    assert_unchanged(before, snapshot(env))


def test_a_finite_result_beyond_the_bound_is_a_divergence() -> None:
    env = gym.make("trailer_env/Reverse-v0", fidelity=1)
    core = env.unwrapped.core
    # u = 1500 m/s with one substep lands at |u| = 1.8e8: the retry (8 substeps) at 17 m/s.
    # Lowering the bound to 1 shows the test on finite values without a blow-up.
    core.step_config.obs_settings[OBS_BOUND] = 1.0
    env.reset(seed=0, options={"state": [1500.0, 0.0, 0.1, -0.1]})
    before = snapshot(env)
    beyond = r"\[0\]: the step's result holds a value beyond 1 in magnitude"
    with pytest.raises(FloatingPointError, match=beyond):
        env.step(np.zeros(1))
    assert_unchanged(before, snapshot(env))
    core.step_config.obs_settings[OBS_BOUND] = 1e6
    env.step(np.zeros(1))  # retried with 8 substeps: finite and within the bound
    assert abs(core.z[0, 0]) < 1e6


#: In-range parameters of the issue's report (Coast-v0, planar, auto fidelity).
REPORTED = {
    "n_trailers": 5,
    "M": 834.83,
    "m": 31241.4,
    "l": 0.04825,
    "J0": 0.00182,
    "a": -0.04593,
    "b": -0.004914,
    "s_max": 0.3133,
    "dt": 0.1608,
    "rail_accel_max": 1.45e-5,
    "servo_bandwidth": 29.99,
    "action_mode": "planar",
    "fidelity": {"tolerance": 5.6e-5},
}


def test_a_capped_step_whose_speed_explodes_is_redone() -> None:
    # From this state the capped step (64 substeps) took u from 1.29 to 5.9e6 m/s, flagged
    # only by the AccuracyWarning; its speed grew > 1000-fold, so it is redone with 8 times
    # the substeps, which lands at u = -3.09 m/s.
    env = gym.make("trailer_env/Coast-v0", **REPORTED).unwrapped
    state = [1.28669372, 2.62996153, -0.04801466, -0.08863604, -0.52386798, -0.98456931,
             -1.46374242]  # fmt: skip
    env.reset(seed=0, options={"state": state, "s": 0.29465181802558954})
    with pytest.warns(trailer_env.AccuracyWarning):
        obs, *_ = env.step(np.zeros(2, dtype=np.float32))
    assert env.core.accuracy_exceeded[0]
    assert abs(env.core.z[0, 0]) < 10.0 and abs(obs[0]) < 10.0
    assert np.all(np.isfinite(obs))


def test_divergence_in_the_vector_env_and_sb3_names_the_row() -> None:
    envs = make_vec("trailer_env/Reverse-v0", 3, fidelity=1)
    states = np.array([[1.0, 0.0, 0.1, -0.1], [20000.0, 0.0, 0.1, -0.1], [1.0, 0.0, 0.0, 0.0]])
    envs.reset(seed=0, options={"state": states})
    before = snapshot(envs)
    with pytest.raises(FloatingPointError, match=r"environment\(s\) \[1\]"):
        envs.step(np.zeros((3, 1)))
    assert_unchanged(before, snapshot(envs))
    pytest.importorskip("stable_baselines3")
    from trailer_env.sb3 import ConvoySB3VecEnv

    venv = ConvoySB3VecEnv("trailer_env/Reverse-v0", num_envs=3, fidelity=1)
    venv.reset()
    venv.core.set_row_state(2, states[1])
    z = venv.core.z.copy()
    with pytest.raises(FloatingPointError, match=r"environment\(s\) \[2\]"):
        venv.step(np.zeros((3, 1)))
    np.testing.assert_array_equal(venv.core.z, z)


def test_a_refused_batch_step_restores_the_other_rows_bookkeeping() -> None:
    envs = make_vec("trailer_env/Coast-v0", 2, fidelity=1)
    states = np.array([[1.0, 0.1, 0.2, -0.1], [20000.0, 0.0, 0.1, -0.1]])
    envs.reset(seed=0, options={"state": states})
    core = envs.unwrapped.core
    potential = core.previous_potential.copy()
    before = snapshot(envs)
    with pytest.raises(FloatingPointError, match=r"environment\(s\) \[1\]"):
        envs.step(np.zeros((2, 1)))
    assert_unchanged(before, snapshot(envs))
    np.testing.assert_array_equal(core.previous_potential, potential)


# ---------------------------------------------------------------- 2. bounded cost
def test_an_auto_step_over_the_work_budget_is_refused_before_integrating() -> None:
    env = gym.make("trailer_env/Reverse-v1", n_trailers=256)
    state = np.zeros(258)
    state[0] = 1e8
    env.reset(seed=0, options={"state": state})
    before = snapshot(env)
    start = time.perf_counter()
    with pytest.raises(
        FloatingPointError,
        match=r"2\.57e\+08 body-substeps .* over the budget of 2e\+08 per control step .*"
        r"environment 0 at u = 1e\+08 m/s, omega = 0 rad/s needs 1000000 substeps; nothing was "
        r"stepped",
    ):
        env.step(np.zeros(1))
    assert time.perf_counter() - start < 2.0  # was 20.7 s
    assert_unchanged(before, snapshot(env))
    state[0] = 1.0
    env.reset(options={"state": state})
    env.step(np.zeros(1))  # an ordinary speed is well within the budget


def test_configurations_over_the_work_budget_are_refused_at_construction() -> None:
    assert MAX_STEP_WORK == 2e8
    with pytest.raises(
        ValueError,
        match=r"100 environment\(s\) of 257 bodies \(n_trailers = 256\) with fidelity.substeps "
        r"= 10000 need 2\.57e\+08 body-substeps per control step, over the budget of 2e\+08",
    ):
        make_vec("trailer_env/Reverse-v1", 100, n_trailers=256, fidelity=10_000)
    with pytest.raises(ValueError, match=r"with one substep each need .* over the budget"):
        ConvoyVectorEnv(core_class_of("trailer_env/Reverse-v0"), num_envs=2**20, n_trailers=256)
    make_vec("trailer_env/Reverse-v1", 70, n_trailers=256, fidelity=10_000).close()  # 1.8e8


# ---------------------------------------------------------------- 3. next_step autoreset
def test_next_step_resets_ended_rows_without_integrating_them() -> None:
    envs = make_vec("trailer_env/Reverse-v1", 2)
    folded = [[0.5, 0.0, 2.0, 0.0], [-0.5, 0.0, 0.3, -0.2]]  # row 0 is jackknifed
    envs.reset(seed=0, options={"state": np.array(folded)})
    _, _, terminated, _, _ = envs.step(np.zeros((2, 1)))
    assert terminated.tolist() == [True, False]
    core = envs.unwrapped.core
    core.z[0, 0] = np.inf  # integrating the ended row would raise FloatingPointError
    actions = np.array([[np.nan], [0.3]])  # its action is ignored, NaN included
    obs, reward, terminated, truncated, _ = envs.step(actions)
    assert reward[0] == 0.0 and not terminated[0] and not truncated[0]
    single = gym.make("trailer_env/Reverse-v1")
    single.reset(seed=0, options={"state": folded[0]})
    start, _ = single.reset()
    np.testing.assert_array_equal(obs[0], start)


# ---------------------------------------------------------------- 4. render
def test_vector_env_pickles_after_render_and_caps_its_frames() -> None:
    pytest.importorskip("pygame")
    envs = make_vec("trailer_env/Reverse-v0", 2, render_mode="rgb_array")
    envs.reset(seed=1)
    frames = envs.render()
    assert len(frames) == 2
    for clone in (pickle.loads(pickle.dumps(envs)), copy.deepcopy(envs)):
        np.testing.assert_array_equal(clone.render()[1], frames[1])
    many = make_vec("trailer_env/Reverse-v0", MAX_RENDER_ENVS + 4, render_mode="rgb_array")
    many.reset(seed=1)
    with pytest.warns(UserWarning, match=r"render\(\) draws the first 16 of 20 environments"):
        assert len(many.render()) == MAX_RENDER_ENVS
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert len(many.render()) == MAX_RENDER_ENVS  # warned once


# ---------------------------------------------------------------- 5. options and inputs
SINGLE_REFUSALS: list[tuple[str, dict[str, Any], type[Exception], str]] = [
    ("Reverse-v0", {"seed": 1.5}, TypeError, r"seed must be None or a non-negative integer"),
    ("Reverse-v0", {"seed": True}, TypeError, r"got bool True"),
    ("Reverse-v0", {"seed": -1}, ValueError, r"non-negative integer, got -1"),
    ("Reverse-v0", {"seed": "1"}, TypeError, r"got str '1'"),
    ("Reverse-v0", {"options": {"state": [0.0] * 3}}, ValueError, r"length 4, got shape \(3,\)"),
    ("Reverse-v0", {"options": {"state": [0.0] * 4, "s": 0.6}}, ValueError, r"on the rail"),
    ("Reverse-v0", {"options": {"state": [0.0] * 4, "s_dot": 9.0}}, ValueError, r"stop before"),
    ("Reverse-v0", {"options": {"state": [0.0] * 4, "target": 1}}, ValueError, r"unknown reset"),
    ("Heading-v0", {"options": {"target_heading": "0.1"}}, TypeError, r"got str '0.1'"),
    ("Heading-v0", {"options": {"target_heading": True}}, TypeError, r"got bool True"),
    ("Heading-v0", {"options": {"target_heading": 1e7}}, ValueError, r"\[-1e\+06, 1e\+06\]"),
    ("Heading-v0", {"options": {"target_heading": np.nan}}, ValueError, r"target_heading"),
    ("Dock-v0", {"options": {"target": "abc"}}, TypeError, r"target must be 3 real numbers"),
    ("Dock-v0", {"options": {"target": [True, False, True]}}, TypeError, r"dtype bool"),
    ("Dock-v0", {"options": {"target": ["1", "2", "3"]}}, TypeError, r"dtype <U1"),
    ("Dock-v0", {"options": {"target": [1e308, 0.0, 0.0]}}, ValueError, r"within \+-1e\+06"),
    ("Dock-v0", {"options": {"target": [1.0, 2.0]}}, ValueError, r"3 finite numbers"),
    (
        "Dock-v0",
        {"options": {"state": [0.0] * 4, "s": 5.0, "target": [1.0, 0.0, 0.0]}},
        ValueError,
        r"on the rail",
    ),
]


@pytest.mark.parametrize(("scene", "arguments", "error", "message"), SINGLE_REFUSALS)
def test_a_refused_reset_changes_nothing(
    scene: str, arguments: dict[str, Any], error: type[Exception], message: str
) -> None:
    env = gym.make(f"trailer_env/{scene}")
    env.reset(seed=5)
    env.step(env.action_space.sample() * 0.0)
    before = snapshot(env)
    with pytest.raises(error, match=message):
        env.reset(**arguments)
    assert_unchanged(before, snapshot(env))


def test_a_refused_set_state_before_the_first_reset_does_not_reset() -> None:
    env = gym.make("trailer_env/Heading-v0")
    with pytest.raises(TypeError, match="target_heading"):
        env.unwrapped.set_state([0.0] * 4, target_heading="0.1")
    assert not env.unwrapped._has_reset


def test_good_task_values_and_numpy_seeds_still_work() -> None:
    env = gym.make("trailer_env/Dock-v0")
    first, _ = env.reset(seed=np.int64(3), options={"target": np.array([5.0, 0.5, 0.0])})
    again, _ = env.reset(seed=3, options={"target": [5, 0.5, 0]})
    np.testing.assert_array_equal(first, again)
    assert env.unwrapped.core.target[0].tolist() == [5.0, 0.5, 0.0]
    heading = gym.make("trailer_env/Heading-v0")
    heading.reset(seed=0, options={"target_heading": np.float32(0.25)})
    assert heading.unwrapped.core.target_heading[0] == np.float32(0.25)


@pytest.mark.parametrize(
    ("state", "error", "message"),
    [
        (np.zeros((3, 4), dtype=bool), TypeError, r"got dtype bool"),
        ([["0"] * 4] * 3, TypeError, r"got dtype <U1"),
        (np.zeros((3, 4)) + 1j, TypeError, r"got dtype complex128"),
        ("state", TypeError, r"got str 'state'"),
        (np.zeros((3, 3)), ValueError, r"state must have shape \(3, 4\)"),
        (np.ma.masked_array(np.zeros((3, 4)), mask=True), ValueError, r"masked entries"),
    ],
)
def test_vector_state_options_refuse_coercion_and_change_nothing(
    state: Any, error: type[Exception], message: str
) -> None:
    envs = make_vec("trailer_env/Reverse-v0", 3)
    envs.reset(seed=2)
    before = snapshot(envs)
    with pytest.raises(error, match=message):
        envs.reset(options={"state": state})
    assert_unchanged(before, snapshot(envs))


def test_vector_seeds_are_never_truncated() -> None:
    envs = make_vec("trailer_env/Reverse-v0", 2)
    envs.reset(seed=2)
    before = snapshot(envs)
    refusals = ((1.5, TypeError), ([1, 1.5], TypeError), ([1], ValueError), (-3, ValueError))
    for seed, error in refusals:
        with pytest.raises(error, match="seed"):
            envs.reset(seed=seed)  # type: ignore[arg-type]
        assert_unchanged(before, snapshot(envs))
    envs.reset(seed=np.int32(4))


def test_masked_actions_with_masked_entries_are_refused() -> None:
    env = gym.make("trailer_env/Reverse-v0")
    env.reset(seed=0)
    before = snapshot(env)
    hidden = np.ma.masked_array([0.7], mask=[True])
    masked = r"action is a masked array with masked entries \(1 of 1\)"
    with pytest.raises(ValueError, match=masked):
        env.step(hidden)
    assert_unchanged(before, snapshot(env))
    envs = make_vec("trailer_env/Reverse-v0", 2)
    envs.reset(seed=0)
    before = snapshot(envs)
    with pytest.raises(ValueError, match=r"actions is a masked array with masked entries"):
        envs.step(np.ma.masked_array(np.zeros((2, 1)), mask=[[False], [True]]))
    assert_unchanged(before, snapshot(envs))
    plain = gym.make("trailer_env/Reverse-v0")
    plain.reset(seed=0)
    expected = plain.step(np.array([0.4]))[0]
    np.testing.assert_array_equal(env.step(np.ma.masked_array([0.4], mask=[False]))[0], expected)


def test_sb3_num_envs_is_bounded() -> None:
    pytest.importorskip("stable_baselines3")
    from trailer_env.sb3 import ConvoySB3VecEnv

    bound = r"num_envs must be an integer in \[1, 16777216\], got 1099511627776"
    with pytest.raises(ValueError, match=bound):
        ConvoySB3VecEnv("trailer_env/Reverse-v0", num_envs=2**40)
    with pytest.raises(ValueError, match="num_envs"):
        ConvoySB3VecEnv("trailer_env/Reverse-v0", num_envs=0)
    with pytest.raises(TypeError, match="num_envs"):
        ConvoySB3VecEnv("trailer_env/Reverse-v0", num_envs=True)  # type: ignore[arg-type]
