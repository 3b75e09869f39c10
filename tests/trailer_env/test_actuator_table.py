"""The action modes come from one table: trailer_env.actuator.ACTUATORS."""

from __future__ import annotations

from typing import get_args

import numpy as np
import pytest

from tests.trailer_env.helpers import make
from trailer_env.actuator import ACTUATORS, ActionMode, servo_accel, servo_target_for_accel
from trailer_env.settings import ACTION_MODES, settings_from_kwargs


def test_the_literal_the_settings_and_the_table_agree() -> None:
    assert get_args(ActionMode) == tuple(ACTUATORS) == ACTION_MODES
    assert [ACTUATORS[mode].code for mode in ACTUATORS] == list(range(len(ACTUATORS)))
    with pytest.raises(ValueError, match="action_mode"):
        settings_from_kwargs(action_mode="rocket")


@pytest.mark.parametrize("mode", list(ACTUATORS))
def test_the_table_drives_each_mode(mode: str) -> None:
    spec = ACTUATORS[mode]
    env = make("Reverse", n_trailers=2, action_mode=mode)
    core = env.unwrapped.core
    settings = core.settings
    assert settings.actuator is spec and core.step_config.mode == spec.code
    assert env.action_space.shape == (spec.action_dim,)
    assert core.planar is spec.planar and core.n_common == 2 + 2 * 2 + spec.mass_features
    env.reset(seed=2)
    rng = np.random.default_rng(0)
    for _ in range(10):
        action = rng.uniform(-1.0, 1.0, (1, spec.action_dim))
        expected = core.act.copy()
        spec.row(
            action,
            0,
            expected,
            core.step_config.b,
            core.step_config.s_max,
            settings.rail_accel_max,
            settings.dt,
            settings.servo_frequency,
        )
        core.step(action)
        # The step held exactly the accelerations the table's row function gives.
        np.testing.assert_array_equal(core.step_state.act_backup[0], expected[0])


@pytest.mark.parametrize("mode", list(ACTUATORS))
def test_command_for_accel_inverts_the_actuator_where_it_is_linear(mode: str) -> None:
    spec = ACTUATORS[mode]
    settings = settings_from_kwargs(action_mode=mode)
    s_max, accel_max, w = settings.params.s_max, settings.rail_accel_max, settings.servo_frequency
    s, v = np.array([0.01, -0.02]), np.array([0.001, 0.0])
    wanted = np.array([0.02, -0.01])
    command = spec.command_for_accel(wanted, s, v, s_max, accel_max, w)
    action = np.zeros((2, spec.action_dim))
    action[:, -1] = command  # the lateral axis is the last
    act = np.zeros((2, 6))
    act[:, 0] = settings.params.b
    act[:, 1], act[:, 3] = s, v
    for i in range(2):
        spec.row(action, i, act, settings.params.b, s_max, accel_max, settings.dt, w)
    np.testing.assert_allclose(act[:, 5], wanted, rtol=1e-12, atol=1e-15)


def test_the_servo_inverse_is_the_servo_law_inverted() -> None:
    s, v, w = 0.05, 0.01, 5.0
    target = servo_target_for_accel(np.array([0.03]), np.array([s]), np.array([v]), w)[0]
    assert servo_accel(target, s, v, 0.5, 4.0, 0.05, w) == pytest.approx(0.03, rel=1e-12)
