"""Bad input gets a clear error; good input of any batch shape works."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dynamics import ConvoyParams, energy, inertia_R, rhs, rhs_planar, step_rk4


def test_wrong_state_length_names_the_expected_shape() -> None:
    with pytest.raises(ValueError, match=r"n\+2 = 4"):
        rhs(ConvoyParams(n_trailers=2), np.zeros(3))
    with pytest.raises(ValueError, match="last axis"):
        energy(ConvoyParams(), 1.0)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_state_or_actuator_is_rejected(bad: float) -> None:
    params = ConvoyParams(n_trailers=1)
    with pytest.raises(ValueError, match="z contains non-finite"):
        rhs(params, [1.0, bad, 0.0])
    with pytest.raises(ValueError, match="s_ddot contains non-finite"):
        rhs(params, [1.0, 0.0, 0.0], s_ddot=bad)
    with pytest.raises(ValueError, match="eta contains non-finite"):
        rhs_planar(params, [1.0, 0.0, 0.0], xi=0.1, eta=bad)


def test_actuator_must_broadcast_to_the_batch() -> None:
    with pytest.raises(ValueError, match="does not broadcast"):
        rhs(ConvoyParams(n_trailers=1), np.zeros((4, 3)), s=np.zeros(3))


def test_params_must_be_convoy_params() -> None:
    with pytest.raises(TypeError, match="ConvoyParams"):
        rhs({"n_trailers": 1}, np.zeros(3))  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"substeps": 0}, "substeps must be >= 1"),
        ({"substeps": 1.5}, "substeps must be integers"),
        ({"substeps": [1, 2]}, "batch size"),
    ],
)
def test_bad_substeps(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        step_rk4(ConvoyParams(n_trailers=0), np.zeros((3, 2)), 0.1, **kwargs)


@pytest.mark.parametrize("dt", [0.0, -0.1, np.nan])
def test_bad_dt(dt: float) -> None:
    with pytest.raises(ValueError, match="dt must be"):
        step_rk4(ConvoyParams(n_trailers=0), np.zeros(2), dt)


def test_inertia_R_checks_its_input() -> None:
    with pytest.raises(ValueError, match="length n = 2"):
        inertia_R(ConvoyParams(n_trailers=2), [0.0])


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(0, 5),
    u=st.floats(-5, 5),
    omega=st.floats(-5, 5),
    seed=st.integers(0, 2**32 - 1),
)
def test_free_convoy_is_time_reversible(n: int, u: float, omega: float, seed: int) -> None:
    """With mu = 0 every force is quadratic in the velocities: reversing them keeps
    (u_dot, omega_dot) and flips alpha_dot, so (-u, -omega, alpha)(-t) is a solution."""
    rng = np.random.default_rng(seed)
    params = ConvoyParams(n_trailers=n, mu=0.0, a=rng.uniform(-1, 1))
    z = np.concatenate([[u, omega], rng.uniform(-np.pi, np.pi, n)])
    forward = rhs(params, z)
    backward = rhs(params, np.concatenate([[-u, -omega], z[2:]]))
    np.testing.assert_allclose(backward[:2], forward[:2], rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(backward[2:], -forward[2:], rtol=1e-13, atol=1e-13)


def test_inertia_R_matches_its_closed_form_and_is_positive(rng: np.random.Generator) -> None:
    params = ConvoyParams(n_trailers=3, M=2.0, m=0.7, J=0.3, l=0.9)
    alpha = rng.uniform(-np.pi, np.pi, (50, 3))
    c2 = np.cos(alpha) ** 2
    prefix = np.cumprod(c2, axis=1)
    expected = (
        params.M + params.m * prefix.sum(axis=1) + params.J / params.l**2 * (1 - prefix[:, -1])
    )
    np.testing.assert_allclose(inertia_R(params, alpha), expected, rtol=1e-14)
    assert np.all(inertia_R(params, alpha) > 0)
