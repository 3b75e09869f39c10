"""lqr-adaptive: the LQR re-designed for each episode's drawn parameters."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

from agents.policies.baselines import AdaptiveLQRPolicy, make_baseline
from trailer_env.controllers import LQRController
from trailer_env.randomize import PARAMETERS

REVERSE = "trailer_env/Reverse-v1"


def test_gains_and_actions_are_those_designed_for_the_drawn_parameters() -> None:
    envs = gym.make_vec(
        REVERSE,
        num_envs=5,
        vectorization_mode="vector_entry_point",
        n_trailers=2,
        randomize="mismatch20",
    )
    native = envs.unwrapped
    obs, infos = envs.reset(seed=10)
    policy = make_baseline("lqr-adaptive", native.settings, REVERSE)
    assert isinstance(policy, AdaptiveLQRPolicy)
    actions = policy(policy.observe(native.core, obs))
    for i in range(5):
        drawn = {name: float(infos["params"][name][i]) for name in PARAMETERS}
        params = native.settings.params.replace(**drawn)
        direct = LQRController(dataclasses.replace(native.settings, params=params, randomize=None))
        design = policy.controller(native.core.param_values[i])
        np.testing.assert_array_equal(design.reverse_gains, direct.reverse_gains)
        np.testing.assert_array_equal(design.forward_gains, direct.forward_gains)
        np.testing.assert_array_equal(actions[i], direct(obs[i]))
    # The draws move the gains (mu and a by up to 20 %): not the nominal design.
    nominal = LQRController(native.settings)
    assert not np.array_equal(
        policy.controller(native.core.param_values[0]).reverse_gains, nominal.reverse_gains
    )
    with pytest.raises(ValueError, match="needs each episode's drawn parameters"):
        policy(obs)


def test_without_randomisation_it_is_the_lqr() -> None:
    envs = gym.make_vec(REVERSE, num_envs=4, vectorization_mode="vector_entry_point", n_trailers=3)
    obs, _ = envs.reset(seed=1)
    settings = envs.unwrapped.settings
    adaptive = make_baseline("lqr-adaptive", settings, REVERSE)
    lqr = make_baseline("lqr", settings, REVERSE)
    np.testing.assert_array_equal(adaptive(obs), lqr(obs))
    np.testing.assert_array_equal(adaptive(adaptive.observe(envs.unwrapped.core, obs)), lqr(obs))
