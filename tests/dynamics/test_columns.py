"""The named columns of ``dynamics.columns`` are the layout the model and the kernels use."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from dynamics.columns import (
    ACT_WIDTH,
    ALPHA,
    ETA,
    ETA_DDOT,
    ETA_DOT,
    OMEGA,
    XI,
    XI_DDOT,
    XI_DOT,
    U,
    theta_column,
    x_column,
    y_column,
)
from dynamics.model import planar_actuator, state_component_name


@pytest.mark.parametrize("n", [0, 1, 3])
def test_state_columns_are_the_documented_components(n: int) -> None:
    names = [state_component_name(column, n) for column in range(n + 5)]
    assert names[U] == "u"
    assert names[OMEGA] == "omega"
    assert [names[ALPHA + k] for k in range(n)] == [f"alpha_{k + 1}" for k in range(n)]
    assert (names[x_column(n)], names[y_column(n)], names[theta_column(n)]) == ("x", "y", "theta")
    assert theta_column(n) == n + 4


def test_act_columns_are_the_actuator_arguments() -> None:
    act = planar_actuator((1,), xi=1.0, eta=2.0, xi_dot=3.0, eta_dot=4.0, xi_ddot=5.0, eta_ddot=6.0)
    assert act.shape == (1, ACT_WIDTH)
    assert [act[0, c] for c in (XI, ETA, XI_DOT, ETA_DOT, XI_DDOT, ETA_DDOT)] == [1, 2, 3, 4, 5, 6]


def test_pose_columns_compile_in_numba() -> None:
    @njit
    def pose(row: np.ndarray, n: int) -> tuple[float, float, float]:
        return row[x_column(n)], row[y_column(n)], row[theta_column(n)]

    assert pose(np.arange(7.0), 2) == (4.0, 5.0, 6.0)
