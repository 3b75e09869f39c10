"""Fixed-step integration: conservation, energy balance, order, batching."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics import ConvoyParams, Stepper, energy, rhs, simulate, step_rk4


def _state(rng: np.random.Generator, n: int, speed: float = 1.0) -> np.ndarray:
    z = np.empty(n + 2)
    z[0] = speed * rng.choice([-1.0, 1.0]) * rng.uniform(0.5, 1.5)
    z[1] = rng.uniform(-0.5, 0.5)
    z[2:] = rng.uniform(-0.8, 0.8, n)
    return z


@pytest.mark.parametrize("n", [0, 1, 3, 6])
def test_energy_is_conserved_without_actuation(rng: np.random.Generator, n: int) -> None:
    params = ConvoyParams(n_trailers=n, mu=0.0)
    z0 = _state(rng, n)
    plain = simulate(params, z0, 0.05, 4000, substeps=2)
    exact = simulate(params, z0, 0.05, 4000, substeps=2, preserve_energy=True)
    e0 = energy(params, z0)
    plain_drift = np.max(np.abs(energy(params, plain.z) / e0 - 1.0))
    exact_drift = np.max(np.abs(energy(params, exact.z) / e0 - 1.0))
    assert plain_drift < 1e-5
    assert exact_drift < 5e-15
    # The rescaling changes the solution by no more than RK4's own error.
    assert np.max(np.abs(plain.z[-1] - exact.z[-1])) < 1e-3


def test_energy_is_conserved_with_the_mass_at_rest_off_centre(rng: np.random.Generator) -> None:
    params = ConvoyParams(n_trailers=2, mu=0.4, b=0.3)
    z0 = _state(rng, 2)
    run = simulate(params, z0, 0.05, 2000, substeps=2, s0=0.2, preserve_energy=True)
    e = energy(params, run.z, s=0.2)
    assert np.max(np.abs(e / e[0] - 1.0)) < 5e-15


def test_preserve_energy_refuses_a_moving_mass() -> None:
    params = ConvoyParams(n_trailers=1, mu=0.3)
    with pytest.raises(ValueError, match="preserve_energy"):
        step_rk4(params, [1.0, 0.0, 0.1], 0.1, s_dot=0.1, preserve_energy=True)


def _rail_power(
    params: ConvoyParams, z: np.ndarray, s: np.ndarray, s_dot: np.ndarray, s_ddot: float
) -> np.ndarray:
    """F_rail s_dot, F_rail = mu (b omega_dot + s_ddot + omega u - omega^2 s) (physics.md s. 9)."""
    z_dot = rhs(params, z, s, s_dot, s_ddot)
    u, omega, omega_dot = z[..., 0], z[..., 1], z_dot[..., 1]
    force = params.mu * (params.b * omega_dot + s_ddot + omega * u - omega**2 * s)
    return force * s_dot


@pytest.mark.parametrize("n", [0, 2, 4])
def test_energy_balance_equals_actuator_work(rng: np.random.Generator, n: int) -> None:
    params = ConvoyParams(n_trailers=n, mu=0.5, b=0.4, a=0.3)
    z0 = _state(rng, n)
    s_ddot = 0.6
    dt, steps = 0.005, 400  # 2 s; the mass runs from s = -0.25 past the centre
    run = simulate(params, z0, dt, steps, substeps=1, s0=-0.25, s_dot0=-0.2, s_ddot=s_ddot)
    e = energy(params, run.z, run.s, run.s_dot)
    power = _rail_power(params, run.z, run.s, run.s_dot, s_ddot)
    # Composite Simpson over the samples (even number of intervals).
    work = dt / 3.0 * (power[0] + power[-1] + 4.0 * power[1:-1:2].sum() + 2.0 * power[2:-1:2].sum())
    assert abs(e[-1] - e[0]) > 1e-3  # the actuator really changes the energy
    assert e[-1] - e[0] == pytest.approx(work, rel=1e-8, abs=1e-10)


def test_rk4_is_fourth_order(rng: np.random.Generator) -> None:
    params = ConvoyParams(n_trailers=3, mu=0.3)
    z0 = _state(rng, 3)
    kwargs = {"s": 0.1, "s_dot": 0.05, "s_ddot": -0.3}
    reference, _, _ = step_rk4(params, z0, 1.0, substeps=4096, **kwargs)
    errors = [
        np.max(np.abs(step_rk4(params, z0, 1.0, substeps=k, **kwargs)[0] - reference))
        for k in (16, 32, 64)
    ]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - 4.0) < 0.3), orders


def test_the_mass_moves_exactly_as_a_quadratic() -> None:
    params = ConvoyParams(n_trailers=2)
    _, s, s_dot = step_rk4(
        params, [1.0, 0.2, 0.1, 0.0], 0.3, substeps=3, s=0.05, s_dot=-0.1, s_ddot=0.7
    )
    assert s == pytest.approx(0.05 - 0.1 * 0.3 + 0.5 * 0.7 * 0.09, abs=1e-15)
    assert s_dot == pytest.approx(-0.1 + 0.7 * 0.3, abs=1e-15)


def test_batched_steps_equal_single_steps_bitwise(rng: np.random.Generator) -> None:
    params = ConvoyParams(n_trailers=3)
    batch = np.stack([_state(rng, 3) for _ in range(300)])  # several parallel chunks
    s_ddot = rng.uniform(-1, 1, 300)
    substeps = rng.integers(1, 6, 300)
    together, s_all, _ = step_rk4(params, batch, 0.05, substeps=substeps, s_ddot=s_ddot)
    for i in (0, 63, 64, 150, 299):
        alone, s_one, _ = step_rk4(
            params, batch[i], 0.05, substeps=int(substeps[i]), s_ddot=s_ddot[i]
        )
        np.testing.assert_array_equal(together[i], alone)
        assert s_all[i] == s_one


def test_leading_axes_are_kept(rng: np.random.Generator) -> None:
    params = ConvoyParams(n_trailers=1)
    z = rng.uniform(-1, 1, (2, 3, 3))
    z_new, s, s_dot = step_rk4(params, z, 0.1, s_ddot=np.ones((2, 3)))
    assert z_new.shape == (2, 3, 3)
    assert s.shape == s_dot.shape == (2, 3)


def test_stepper_checks_shapes() -> None:
    stepper = Stepper(ConvoyParams(n_trailers=2))
    with pytest.raises(ValueError, match="expected z of shape"):
        stepper.step(np.zeros((4, 5)), np.zeros((4, 6)), 0.1, np.ones(4, dtype=np.int64))


def test_pose_columns_follow_the_reconstruction_equations() -> None:
    # Straight convoy reversing at constant speed: the cart runs straight backwards.
    params = ConvoyParams(n_trailers=2, mu=0.0)
    z0 = np.array([-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.25])
    run = simulate(params, z0, 0.1, 10)
    np.testing.assert_allclose(run.z[-1, 4:], [-np.cos(0.25), -np.sin(0.25), 0.25], atol=1e-14)
