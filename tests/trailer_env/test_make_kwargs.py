"""Property test over ``gym.make`` / ``gym.make_vec`` keyword arguments, all four ids.

Every example is a random subset of the environments' keywords with values drawn
from good values, range edges and wrong types (bools, strings, complex, None, huge
ints, 1e300, 1e-300, NaN, inf, lists), plus unknown names. The outcome must be one
of two: an environment that resets and steps once with finite observation, reward
and info; or a ValueError or TypeError whose message names one of the arguments
given. Never another exception, never a hang (hypothesis' deadline).
"""

from __future__ import annotations

import dataclasses
import math
import re
import warnings
from datetime import timedelta
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dynamics import ConvoyParams
from dynamics.params import MAX_TRAILERS
from tests.trailer_env.helpers import SCENE_IDS
from trailer_env.fidelity import Fidelity

#: Values of the wrong type or absurd magnitude, tried for every keyword.
HOSTILE: list[Any] = [
    True,
    False,
    "0.1",
    "auto",
    1j,
    None,
    10**400,
    -(10**400),
    2**63,
    1e300,
    -1e300,
    1e-300,
    math.nan,
    math.inf,
    -math.inf,
    [1.0],
    {"substeps": 1},
    0,
    -1,
]

#: Good values and range edges of every keyword the environments accept.
GOOD: dict[str, list[Any]] = {
    "n_trailers": [0, 1, 2, 3, np.int64(4), 8.0, 32, MAX_TRAILERS],
    "params": [
        ConvoyParams(n_trailers=1),
        ConvoyParams(n_trailers=3, mu=0.0),
        # The smallest and the largest convoys the ranges allow, all ratios at their bounds.
        ConvoyParams(M=1e-6, m=5e-4, mu=5e-4, l=1e-6, a=-5e-4, b=5e-4, s_max=5e-4, J=0.0, J0=1e-18),
        ConvoyParams(M=1e6, m=1e6, mu=1e6, l=1e6, a=1e6, b=-1e6, s_max=1e6, J=1e17, J0=1e18),
    ],
    "dt": [0.05, 0.02, np.float32(0.1), 1e-5, 0.2, 0.35, 1],
    "fidelity": [
        None,
        "auto",
        "rk4",
        "dopri5",
        "rk4-energy",
        1,
        4,
        10_000,
        {"substeps": 2},
        {"tolerance": 1e-13},
        {"tolerance": 1e-3, "max_substeps": 1},
        {"integrator": "dopri5", "tolerance": 1e-6},
        Fidelity(substeps=3),
    ],
    "action_mode": ["servo", "accel", "planar"],
    "rail_accel_max": [4.0, 1e-6, 0.5, 20],
    "servo_bandwidth": [5.0, 1e-6, 1e6, 50],
    "singular_band": [0.3, 0.0, 0.999],
    "fold_angle": [math.pi / 2, math.pi, 1e-3, 1],
    "M": [1.0, 1e-6, 1e6, 3],
    "J0": [0.2, 1e-18, 1e18, 1e-3],
    "a": [0.5, -1e6, 1e6, 0.0, -0.3],
    "m": [1.0, 1e-6, 1e6, 0.2],
    "J": [0.1, 0.0, 1e18, 1e-4],
    "l": [1.0, 1e-6, 1e6, 0.01, 3],
    "mu": [0.5, 0.0, 1e6, 0.05],
    "b": [1.0, -1e6, 1e6, 0.0, -0.5],
    "s_max": [0.5, 1e-6, 1e6, 0.1],
    "render_mode": [None, "rgb_array"],
}
#: Names the environments do not take (TorchRL probes the first ones).
UNKNOWN = ["frameskip", "full_action_space", "repeat_action_probability", "wheelbase", "Mu"]


def _kwargs() -> st.SearchStrategy[dict[str, Any]]:
    # One value in 25 hostile, so that about a third of the examples build an env.
    value_of = {
        name: st.integers(0, 24).flatmap(
            lambda k, good=good: st.sampled_from(HOSTILE if k == 13 else good)
        )
        for name, good in GOOD.items()
    }
    known = st.fixed_dictionaries({}, optional=value_of)
    unknown = st.dictionaries(st.sampled_from(UNKNOWN), st.sampled_from([0, 1.0, "x"]), max_size=1)
    return st.tuples(known, unknown, st.integers(0, 9)).map(
        lambda parts: {**parts[0], **parts[1]} if parts[2] == 7 else parts[0]
    )


def _names_an_argument(message: str, kwargs: dict[str, Any]) -> bool:
    """Whether the message names a keyword given (a field of a given ``params`` counts)."""
    names = set(kwargs)
    if "params" in kwargs:
        names |= {field.name for field in dataclasses.fields(ConvoyParams)}
    return any(re.search(rf"(?<!\w){re.escape(name)}(?!\w)", message) for name in names)


def _all_finite(info: dict[str, Any]) -> bool:
    return all(np.all(np.isfinite(np.asarray(value, dtype=np.float64))) for value in info.values())


def _check_outcome(env_id: str, kwargs: dict[str, Any], vector: bool) -> None:
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # J >= m l^2, gymnasium's checker's notes
            if vector:
                kwargs = {k: v for k, v in kwargs.items() if k != "render_mode"}
                env: Any = gym.make_vec(
                    env_id, num_envs=3, vectorization_mode="vector_entry_point", **kwargs
                )
            else:
                env = gym.make(env_id, **kwargs)
    except (ValueError, TypeError) as error:
        assert _names_an_argument(str(error), kwargs), (kwargs, error)
        return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        obs, info = env.reset(seed=0)
        assert np.all(np.isfinite(obs)) and _all_finite(info), (kwargs, obs, info)
        action = np.full(env.action_space.shape, 0.5, dtype=np.float32)
        obs, reward, _terminated, _truncated, info = env.step(action)
    assert np.all(np.isfinite(obs)) and np.all(np.isfinite(reward)), (kwargs, obs, reward)
    assert _all_finite(info), (kwargs, info)
    env.close()


SETTINGS = {
    "deadline": timedelta(seconds=10),
    "suppress_health_check": [HealthCheck.too_slow],
    "derandomize": True,
}


@settings(max_examples=300, **SETTINGS)  # type: ignore[arg-type]
@given(env_id=st.sampled_from(SCENE_IDS), kwargs=_kwargs(), vector=st.booleans())
def test_make_gives_a_working_env_or_an_error_naming_an_argument(
    env_id: str, kwargs: dict[str, Any], vector: bool
) -> None:
    _check_outcome(env_id, kwargs, vector)


@pytest.mark.slow
@settings(max_examples=20_000, **{**SETTINGS, "derandomize": False})  # type: ignore[arg-type]
@given(env_id=st.sampled_from(SCENE_IDS), kwargs=_kwargs(), vector=st.booleans())
def test_make_gives_a_working_env_or_an_error_naming_an_argument_at_length(
    env_id: str, kwargs: dict[str, Any], vector: bool
) -> None:
    _check_outcome(env_id, kwargs, vector)


@pytest.mark.parametrize("env_id", SCENE_IDS)
def test_every_hostile_value_of_every_keyword_is_refused_or_works(env_id: str) -> None:
    """The exhaustive single-keyword version: each keyword alone, each hostile value."""
    for name in GOOD:
        for value in HOSTILE:
            _check_outcome(env_id, {name: value}, vector=False)


def test_unknown_keywords_are_a_type_error_for_torchrl() -> None:
    """Python's wording: TorchRL drops the keyword it probes when it reads it."""
    with pytest.raises(TypeError, match="unexpected keyword argument 'frameskip'"):
        gym.make("trailer_env/Reverse-v0", frameskip=4)
    with pytest.raises(TypeError, match="argument 'Mu'; unexpected keyword argument 'frameskip'"):
        gym.make("trailer_env/Reverse-v0", frameskip=4, Mu=0.1)
