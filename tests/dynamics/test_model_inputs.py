"""Bad input gets a clear error; good input of any batch shape works."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dynamics import (
    ConvoyParams,
    Stepper,
    body_poses,
    energy,
    inertia_R,
    is_jackknifed,
    rhs,
    rhs_planar,
    simulate,
    singular_margin,
    step_rk4,
    step_rk4_planar,
)
from dynamics.integrate import MAX_SUBSTEPS


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
        ({"substeps": 0}, r"substeps must be an integer in \[1, 100000000\], got 0"),
        ({"substeps": -5}, "got -5"),
        ({"substeps": 2**63}, "got 9223372036854775808"),
        ({"substeps": MAX_SUBSTEPS + 1}, "substeps must be"),
        ({"substeps": np.array([1, 0, 2])}, "substeps must be >= 1"),
        ({"substeps": np.array([1, 2**63, 2], dtype=np.uint64)}, "substeps must be >= 1"),
        ({"substeps": 1.5}, "substeps must be integers"),
        ({"substeps": [1, 2]}, "batch size"),
    ],
)
def test_bad_substeps(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        step_rk4(ConvoyParams(n_trailers=0), np.zeros((3, 2)), 0.1, **kwargs)


@pytest.mark.parametrize("substeps", [True, "2", None, np.array([True, False, True])])
def test_substeps_of_the_wrong_type(substeps: object) -> None:
    with pytest.raises(TypeError, match="substeps must be integers"):
        step_rk4(ConvoyParams(n_trailers=0), np.zeros((3, 2)), 0.1, substeps=substeps)


@pytest.mark.parametrize("dt", [0.0, -0.1, np.nan, np.inf, 10**400])
def test_bad_dt(dt: float) -> None:
    with pytest.raises(ValueError, match="dt must be"):
        step_rk4(ConvoyParams(n_trailers=0), np.zeros(2), dt)


@pytest.mark.parametrize("dt", ["0.1", True, None, 0.1j])
def test_dt_of_the_wrong_type(dt: object) -> None:
    with pytest.raises(TypeError, match="dt must be a real number"):
        step_rk4(ConvoyParams(n_trailers=0), np.zeros(2), dt)  # type: ignore[arg-type]


@pytest.mark.parametrize("z", [["1", "0"], [True, False], [1j, 0.0], [None, 0.0]])
def test_states_that_are_not_real_numbers_are_a_type_error(z: object) -> None:
    with pytest.raises(TypeError, match="z must be real numbers"):
        rhs(ConvoyParams(n_trailers=0), z)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="s must be real numbers"):
        rhs(ConvoyParams(n_trailers=0), [1.0, 0.0], s="0.1")


def test_integer_states_are_converted_to_float() -> None:
    """Documented: a state of ints is read as floats (step_rk4 returns a new array)."""
    params = ConvoyParams(n_trailers=2, mu=0.0)
    from_ints, _, _ = step_rk4(params, np.array([1, 0, 0, 0]), 0.1)
    from_floats, _, _ = step_rk4(params, np.array([1.0, 0.0, 0.0, 0.0]), 0.1)
    np.testing.assert_array_equal(from_ints, from_floats)
    assert from_ints.dtype == np.float64


class TestStepper:
    """Stepper.step works in place on trusted arrays, but checks their types and shapes."""

    params = ConvoyParams(n_trailers=2)

    def arrays(self, rows: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        z = np.tile([1.0, 0.1, 0.2, -0.1], (rows, 1))
        act = np.zeros((rows, 6))
        act[:, 0] = self.params.b
        return z, act, np.ones(rows, dtype=np.int64)

    def test_substeps_of_the_wrong_length_is_refused(self) -> None:
        z, act, _ = self.arrays(1000)
        with pytest.raises(ValueError, match=r"substeps must have shape \(1000,\), got \(1,\)"):
            Stepper(self.params).step(z, act, 0.1, np.ones(1, dtype=np.int64))

    @pytest.mark.parametrize("bad", [0, -5, MAX_SUBSTEPS + 1])
    def test_substep_counts_out_of_range(self, bad: int) -> None:
        z, act, counts = self.arrays(4)
        counts[2] = bad
        before = z.copy()
        with pytest.raises(ValueError, match=f"got {bad} at row 2"):
            Stepper(self.params).step(z, act, 0.1, counts)
        np.testing.assert_array_equal(z, before)

    def test_integer_state_is_refused_not_truncated(self) -> None:
        z, act, counts = self.arrays(3)
        with pytest.raises(TypeError, match="z must be a float64 numpy array"):
            Stepper(self.params).step(z.astype(np.int64), act, 0.1, counts)
        with pytest.raises(TypeError, match="act must be a float64"):
            Stepper(self.params).step(z, act.tolist(), 0.1, counts)  # type: ignore[arg-type]
        with pytest.raises(TypeError, match="substeps must be an int64"):
            Stepper(self.params).step(z, act, 0.1, counts.astype(np.int32))

    @pytest.mark.parametrize("dt", [0.0, -1.0, np.nan, np.inf])
    def test_bad_dt(self, dt: float) -> None:
        z, act, counts = self.arrays(3)
        with pytest.raises(ValueError, match="dt must be"):
            Stepper(self.params).step(z, act, dt, counts)

    def test_target_energy_shape(self) -> None:
        z, act, counts = self.arrays(3)
        with pytest.raises(
            ValueError, match=r"target_energy must be a numpy array of shape \(3,\)"
        ):
            Stepper(self.params).step(z, act, 0.1, counts, np.zeros(1))

    def test_valid_call_matches_step_rk4(self) -> None:
        z, act, counts = self.arrays(3)
        Stepper(self.params).step(z, act, 0.1, counts)
        expected, _, _ = step_rk4(self.params, [1.0, 0.1, 0.2, -0.1], 0.1)
        np.testing.assert_allclose(z, np.tile(expected, (3, 1)), rtol=0, atol=1e-15)


def test_overflow_from_finite_input_raises_and_names_the_component() -> None:
    params = ConvoyParams()
    with pytest.raises(FloatingPointError, match="rhs overflowed: its u component"):
        rhs(params, [1e200, 1e200, 0.2, -0.1])
    with pytest.raises(FloatingPointError, match="energy overflowed"):
        energy(params, [1e200, 1e200, 0.2, -0.1])
    with pytest.raises(FloatingPointError, match="RK4 step overflowed"):
        step_rk4(params, [1e200, 1e200, 0.2, -0.1], 0.1)
    with pytest.raises(FloatingPointError, match="RK4 step overflowed"):
        step_rk4_planar(params, [1e200, 1e200, 0.2, -0.1], 0.1, xi=1.0, eta=0.0)
    with pytest.raises(FloatingPointError, match="simulate overflowed"):
        simulate(params, [1e100, 1e100, 0.2, -0.1], 0.1, 3)


def test_simulate_arguments() -> None:
    params = ConvoyParams(n_trailers=2)
    with pytest.raises(ValueError, match="z0 holds no state"):
        simulate(params, np.zeros((0, 4)), 0.1, 3)
    for steps in (np.inf, -1, 2.5, 2**40):
        with pytest.raises(ValueError, match="n_steps must be an integer"):
            simulate(params, np.zeros(4), 0.1, steps)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="n_steps must be an integer"):
        simulate(params, np.zeros(4), 0.1, "3")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="more than 2147483648"):
        simulate(params, np.zeros((1000, 4)), 0.1, 10**6)
    trajectory = simulate(params, np.zeros(4), 0.1, 3.0)  # type: ignore[arg-type]
    assert trajectory.z.shape == (4, 4)
    np.testing.assert_array_equal(trajectory.t, [0.0, 0.1, 0.2, 0.30000000000000004])


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


def test_poses_and_singular_tests_refuse_non_numbers() -> None:
    with pytest.raises(TypeError, match="l must be a real number"):
        body_poses("1", 0.0, 0.0, 0.0, [0.1])  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="y must be real numbers"):
        body_poses(1.0, 0.0, "0", 0.0, [0.1])
    with pytest.raises(TypeError, match="alpha must be real numbers"):
        is_jackknifed(["0.1"])
    with pytest.raises(TypeError, match="fold_angle must be a real number"):
        is_jackknifed([0.1], fold_angle=True)
    with pytest.raises(TypeError, match="alpha must be real numbers"):
        singular_margin([[True, False]])
    assert singular_margin(np.array([[0, 0]])).tolist() == [1.0]  # ints are read as floats


def test_empty_batches_give_empty_results() -> None:
    params = ConvoyParams(n_trailers=2)
    z, s, s_dot = step_rk4(params, np.zeros((0, 4)), 0.1)
    assert z.shape == (0, 4) and s.shape == (0,) and s_dot.shape == (0,)
    assert rhs(params, np.zeros((0, 4))).shape == (0, 4)
    assert energy(params, np.zeros((0, 4))).shape == (0,)


def test_rail_and_planar_twins_are_one_implementation_bit_for_bit() -> None:
    from dynamics import ConvoyParams as Params
    from dynamics.integrate import step_rk4, step_rk4_planar
    from dynamics.model import energy, energy_planar, rhs, rhs_planar

    p = Params(n_trailers=2)
    z = np.array([[-1.0, 0.1, 0.2, -0.1], [0.8, -0.2, 0.05, 0.3]])
    s, s_dot, s_ddot = np.array([0.1, -0.2]), np.array([0.05, 0.0]), np.array([0.5, -1.0])
    planar = {"xi": p.b, "eta": s, "eta_dot": s_dot}
    np.testing.assert_array_equal(
        rhs(p, z, s, s_dot, s_ddot), rhs_planar(p, z, **planar, eta_ddot=s_ddot)
    )
    np.testing.assert_array_equal(energy(p, z, s, s_dot), energy_planar(p, z, **planar))
    z_rail, s_end, s_dot_end = step_rk4(p, z, 0.05, substeps=3, s=s, s_dot=s_dot, s_ddot=s_ddot)
    z_planar, act = step_rk4_planar(p, z, 0.05, substeps=3, **planar, eta_ddot=s_ddot)
    np.testing.assert_array_equal(z_rail, z_planar)
    np.testing.assert_array_equal(np.stack([s_end, s_dot_end], axis=-1), act[:, [1, 3]])
