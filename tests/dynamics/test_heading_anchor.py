"""The moving mass cannot turn a coasting convoy for good (docs/physics.md, section 9).

K = (I0 + mu (b^2 + s^2)) omega + mu b s_dot + (M a + mu b) u theta obeys
dK/dt = mu s u_dot + (M a + mu b) u_dot theta, so it changes only through u_dot.
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics import ConvoyParams, rhs, simulate


def _anchor(params: ConvoyParams, z: np.ndarray, s: np.ndarray, s_dot: np.ndarray) -> np.ndarray:
    n = params.n_trailers
    u, omega, theta = z[..., 0], z[..., 1], z[..., n + 4]
    inertia = params.I0 + params.mu * (params.b**2 + s**2)
    return (
        inertia * omega
        + params.mu * params.b * s_dot
        + (params.M * params.a + params.mu * params.b) * u * theta
    )


@pytest.mark.parametrize("n", [0, 1, 3])
def test_anchor_changes_only_through_u_dot(rng: np.random.Generator, n: int) -> None:
    params = ConvoyParams(n_trailers=n, a=rng.uniform(-0.5, 0.8))
    z = np.concatenate([rng.normal(size=2), rng.uniform(-1, 1, n), rng.normal(size=3)])
    s, s_dot, s_ddot = rng.uniform(-0.4, 0.4), rng.normal(), rng.normal()
    z_dot = rhs(params, z, s, s_dot, s_ddot)
    u, omega, theta = z[0], z[1], z[n + 4]
    u_dot, omega_dot = z_dot[0], z_dot[1]
    inertia = params.I0 + params.mu * (params.b**2 + s**2)
    coupling = params.M * params.a + params.mu * params.b
    k_dot = (
        inertia * omega_dot
        + 2 * params.mu * s * s_dot * omega
        + params.mu * params.b * s_ddot
        + coupling * (u_dot * theta + u * omega)
    )
    assert k_dot == pytest.approx(
        params.mu * s * u_dot + coupling * u_dot * theta, rel=1e-12, abs=1e-12
    )


def test_a_stroke_of_the_mass_turns_the_sleigh_only_while_it_moves() -> None:
    # n = 0 (the sleigh): u_dot = O(omega^2) stays small, so K is nearly conserved.
    params = ConvoyParams(n_trailers=0)
    z0 = np.array([1.0, 0.0, 0.0, 0.0, 0.0])
    dt = 0.01
    # Push the mass to s = 0.4 and stop it there (0.2 s accelerating, 0.2 s braking).
    push = simulate(params, z0, dt, 20, s_ddot=10.0)
    brake = simulate(params, push.z[-1], dt, 20, s0=push.s[-1], s_dot0=push.s_dot[-1], s_ddot=-10.0)
    coast = simulate(params, brake.z[-1], dt, 2000, s0=brake.s[-1], s_dot0=brake.s_dot[-1])
    assert brake.s_dot[-1] == pytest.approx(0.0, abs=1e-12)
    assert brake.s[-1] == pytest.approx(0.4, abs=1e-12)
    theta_peak = np.max(np.abs(np.concatenate([push.z[:, 4], brake.z[:, 4], coast.z[:, 4]])))
    theta_final = coast.z[-1, 4]
    assert theta_peak > 0.05  # the stroke does turn the cart while the mass moves
    assert abs(coast.z[-1, 1]) < 1e-6  # and the sleigh settles on a straight line
    # K is 0 at the start, so the heading returns (almost) to where it started.
    assert abs(theta_final) < 0.01 * theta_peak
    k_end = _anchor(params, coast.z[-1], coast.s[-1], coast.s_dot[-1])
    coupling = params.M * params.a + params.mu * params.b
    assert theta_final == pytest.approx(k_end / (coupling * coast.z[-1, 0]), rel=1e-4)
