"""The feasibility screen against a hand-solvable system and on Reverse-v0 starts."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import trailer_env  # noqa: F401  (registers the ids)
from agents.oracles.screen import discretise, minimal_stroke, screen_start

GROWTH = 1.0  # lam, 1/s
COUPLING = 0.5  # c: x' = lam x + c s
DT = 0.01


def one_mode_system(dt: float = DT) -> tuple[np.ndarray, np.ndarray]:
    """x' = lam x + c s with the mass (s, s_dot) driven by its acceleration, discretised."""
    a_matrix = np.array([[GROWTH, COUPLING, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    return discretise(a_matrix, np.array([0.0, 0.0, 1.0]), dt)


def hand_stroke(x0: float, horizon: float) -> float:
    """S = lam |x0| / (c (1 - exp(-lam T))): bang-bang s = -sign(x0) S, back to 0 at T."""
    return GROWTH * abs(x0) / (COUPLING * (1.0 - math.exp(-GROWTH * horizon)))


@pytest.mark.parametrize(("x0", "horizon"), [(0.1, 1.0), (0.1, 2.0), (-0.05, 3.0)])
def test_minimal_stroke_matches_the_closed_form(x0: float, horizon: float) -> None:
    a_d, b_d = one_mode_system()
    result = minimal_stroke(
        a_d,
        b_d,
        np.array([x0, 0.0, 0.0]),
        position=1,
        speed=2,
        speed_max=1e3,
        accel_max=1e4,
        steps=round(horizon / DT),
    )
    # The discrete LP approaches the continuous optimum as dt -> 0 (error of order lam dt).
    assert result.stroke == pytest.approx(hand_stroke(x0, horizon), rel=0.02)
    assert result.unstable_eigenvalues.size == 1
    assert result.unstable_eigenvalues[0].real == pytest.approx(math.exp(GROWTH * DT))


@pytest.mark.parametrize(("x0", "recoverable"), [(0.09, True), (-0.09, True), (0.11, False)])
def test_recoverable_set_is_the_interval_c_s_max_over_lam(x0: float, recoverable: bool) -> None:
    s_max = 0.2  # recoverable set |x0| < c s_max / lam = 0.1 for a long horizon
    a_d, b_d = one_mode_system(dt=0.02)
    result = minimal_stroke(
        a_d,
        b_d,
        np.array([x0, 0.0, 0.0]),
        position=1,
        speed=2,
        speed_max=1e3,
        accel_max=1e4,
        steps=300,
        s_max=s_max,  # 6 s: exp(-6) = 0.25 %
    )
    assert result.recoverable is recoverable
    assert result.stroke == pytest.approx(GROWTH * abs(x0) / COUPLING, rel=0.03)


def test_tight_speed_bound_makes_it_infeasible() -> None:
    a_d, b_d = one_mode_system()
    result = minimal_stroke(
        a_d,
        b_d,
        np.array([0.1, 0.0, 0.0]),
        position=1,
        speed=2,
        speed_max=1e-3,
        accel_max=1e4,
        steps=round(1.0 / DT),
    )
    assert result.stroke == math.inf
    assert not result.recoverable


def test_bad_arguments_raise() -> None:
    a_d, b_d = one_mode_system()
    with pytest.raises(ValueError, match="shapes"):
        minimal_stroke(
            a_d, b_d, np.zeros(2), position=1, speed=2, speed_max=1, accel_max=1, steps=5
        )
    with pytest.raises(ValueError, match="steps"):
        minimal_stroke(
            a_d, b_d, np.zeros(3), position=1, speed=2, speed_max=1, accel_max=1, steps=0
        )
    with pytest.raises(ValueError, match="dt"):
        discretise(np.eye(2), np.ones(2), 0.0)


def test_convoy_screen_grows_with_the_number_of_trailers() -> None:
    # Seed 1000 of Reverse-v0: identical trailers give a Jordan block in the
    # linearisation, so every trailer adds a condition and the stroke grows with n.
    strokes = []
    for n in (1, 2, 3):
        env = gym.make("trailer_env/Reverse-v0", n_trailers=n).unwrapped
        env.reset(seed=1000)
        result = screen_start(env.settings, env.core.z[0], horizon=5.0)
        assert result.unstable_eigenvalues.size == n + 1
        strokes.append(result.stroke)
    assert strokes[0] < strokes[1] < strokes[2]
    assert np.isfinite(strokes).all()
