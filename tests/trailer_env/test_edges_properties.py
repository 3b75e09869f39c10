"""Property tests of issue 21: any reset options, seed or action either works or raises
ValueError/TypeError, and a refusal leaves the observation, the state and the
generator's state as they were (100 examples by default, 2,000 under ``-m slow``)."""

from __future__ import annotations

import warnings
from functools import cache
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import trailer_env  # noqa: F401  (registers the ids)

SCENES = ("trailer_env/Reverse-v0", "trailer_env/Heading-v0", "trailer_env/Dock-v0")
KEYS = ("state", "s", "s_dot", "target_heading", "target", "reset_mask", "bogus")

numbers = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(-2.0, 2.0),
    st.integers(-(2**70), 2**70),
    st.booleans(),
    st.complex_numbers(max_magnitude=10.0),
)
scalars = st.one_of(numbers, st.none(), st.text(max_size=3), st.just(np.float32(0.1)))
vectors = st.one_of(
    st.lists(st.floats(-3.0, 3.0), min_size=0, max_size=6),
    st.lists(numbers, min_size=2, max_size=5),
    st.lists(st.text(max_size=2), min_size=3, max_size=4),
    st.integers(1, 6).map(lambda size: np.ma.masked_array(np.zeros(size), mask=[True] * size)),
    st.integers(1, 6).map(lambda size: np.zeros(size, dtype=bool)),
)
values = st.one_of(scalars, vectors)
options = st.one_of(st.none(), st.dictionaries(st.sampled_from(KEYS), values, max_size=4))
seeds = st.one_of(
    st.none(), st.integers(-3, 2**40), st.floats(-2.0, 2.0), st.booleans(), st.text(max_size=2)
)
actions = st.one_of(values, st.integers(1, 3).map(lambda size: np.linspace(-2.0, 2.0, size)))


@cache
def environment(env_id: str) -> Any:
    return gym.make(env_id).unwrapped


def snapshot(env: Any) -> tuple:
    core = env.core
    return (
        core.z.copy(),
        core.act[:, :4].copy(),
        core.obs.copy(),
        repr(env.np_random.bit_generator.state),
    )


def assert_unchanged(before: tuple, after: tuple) -> None:
    for first, second in zip(before[:3], after[:3], strict=True):
        np.testing.assert_array_equal(first, second)
    assert before[3] == after[3]


def check(env_id: str, seed: Any, option: Any, action: Any) -> None:
    env = environment(env_id)
    env.reset(seed=0)
    before = snapshot(env)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            env.reset(seed=seed, options=option)
        except (ValueError, TypeError):
            assert_unchanged(before, snapshot(env))
        env.reset(seed=0)
        before = snapshot(env)
        try:
            env.step(action)
        except (ValueError, TypeError):
            assert_unchanged(before, snapshot(env))


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(SCENES), seeds, options, actions)
def test_any_input_works_or_is_refused_changing_nothing(
    env_id: str, seed: Any, option: Any, action: Any
) -> None:
    check(env_id, seed, option, action)


@pytest.mark.slow
@settings(max_examples=2000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(SCENES), seeds, options, actions)
def test_any_input_works_or_is_refused_changing_nothing_at_length(
    env_id: str, seed: Any, option: Any, action: Any
) -> None:
    check(env_id, seed, option, action)


vector_states = st.one_of(
    values,
    st.tuples(st.integers(1, 4), st.integers(3, 5)).map(lambda shape: np.zeros(shape)),
    st.sampled_from([np.bool_, np.complex128, np.int64, np.float32]).map(
        lambda dtype: np.ones((3, 4), dtype=dtype)
    ),
    st.lists(st.lists(numbers, min_size=4, max_size=4), min_size=3, max_size=3),
)
vector_options = st.one_of(
    st.none(),
    st.fixed_dictionaries(
        {},
        optional={
            "state": vector_states,
            "reset_mask": st.one_of(values, st.lists(st.booleans(), min_size=3, max_size=3)),
            "bogus": values,
        },
    ),
)


@cache
def vector_environment() -> Any:
    return gym.make_vec(
        "trailer_env/Reverse-v0", num_envs=3, vectorization_mode="vector_entry_point"
    )


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(seeds, st.lists(seeds, min_size=2, max_size=4)), vector_options, actions)
def test_vector_inputs_work_or_are_refused_changing_nothing(
    seed: Any, option: Any, action: Any
) -> None:
    envs = vector_environment()
    envs.reset(seed=0)
    core = envs.unwrapped.core

    def state() -> tuple:
        generators = envs.unwrapped._generators
        return (core.z.copy(), core.obs.copy(), repr([g.bit_generator.state for g in generators]))

    before = state()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            envs.reset(seed=seed, options=option)
        except (ValueError, TypeError):
            after = state()
            np.testing.assert_array_equal(before[0], after[0])
            np.testing.assert_array_equal(before[1], after[1])
            assert before[2] == after[2]
        envs.reset(seed=0)
        before = state()
        try:
            envs.step(action)
        except (ValueError, TypeError):
            after = state()
            np.testing.assert_array_equal(before[0], after[0])
            assert before[2] == after[2]
