"""Measured stability limits of the integrators against linear stability theory.

How the dimensionless step maps to the eigenvalues. Linearised at the straight
convoy moving at speed u (physics.md section 7; here u = sigma_0 sqrt(2E/(M + n m)))
the reduced state (u, omega, alpha_1..alpha_n) has eigenvalues

    0 (along the energy),  lambda_0 = -(M a / I0) u,  lambda_k = -u / l  (k = 1..n).

A Runge-Kutta step of size h multiplies each eigencomponent by R(h lambda), R the
method's stability function, so going forward (lambda_k < 0) a perturbation decays
iff |R(-x)| < 1 for both dimensionless steps

    x_trailer = h |u| / l = h |lambda_k|,   x_cart = h M a |u| / I0 = h |lambda_0|,

that is iff max(x_trailer, x_cart) < x*, with x* = 2.7853 for RK4 and 3.3066 for
DOPRI5 (the roots of |R(-x)| = 1). By the homogeneity of section 6 (time scales
like 1/sqrt(E)), only these products matter: doubling |u| halves the largest stable h.
A mass mu at rest at (b, 0) rides with the cart: M a -> M a + mu b, I0 -> I0 + mu b^2.

The measurement (bisection on the largest decaying step, the linearised model,
departure times) is ``benchmarks/stability.py``'s, which charts the same quantities:
these tests assert the limits it measures against the theory above, closed forms
and literature values written out here.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numba
import numpy as np
import pytest

from benchmarks import stability
from benchmarks.stability import (
    advance,
    decay_rates,
    departure_time,
    largest_stable_step,
    linearisation,
    perturbed_equilibrium,
    resting_mass_action,
    run_from_node,
)
from benchmarks.stability_theory import (
    DOPRI5_FIXED,
    RK4,
    RK4_ENERGY_PRESERVING,
    real_axis_limit,
    rk4_stability,
)
from dynamics import ConvoyParams, energy, rhs
from dynamics.adaptive import AdaptiveStepper


@pytest.fixture(autouse=True, scope="module")
def _one_thread() -> Iterator[None]:
    """One-state runs gain nothing from the kernel's threads, whose spin-waits cost time."""
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    yield
    numba.set_num_threads(threads)


RK4_LIMIT = real_axis_limit(RK4)
DOPRI5_LIMIT = real_axis_limit(DOPRI5_FIXED)


def test_theoretical_limits() -> None:
    """Literature values: RK4 2.7853 (Hairer and Wanner IV.2), DOPRI5 3.3066."""
    assert abs(RK4_LIMIT - 2.785293563) < 1e-8
    assert abs(DOPRI5_LIMIT - 3.3066) < 1e-4


TRAILER_FASTEST = ConvoyParams(n_trailers=1, a=0.1, mu=0.0)  # M a / I0 = 0.48 < 1 / l = 1
CART_FASTEST = ConvoyParams(n_trailers=1, l=2.0, mu=0.0)  # M a / I0 = 1.11 > 1 / l = 0.5


@pytest.mark.parametrize(
    ("method", "limit"),
    [(RK4, RK4_LIMIT), (RK4_ENERGY_PRESERVING, RK4_LIMIT), (DOPRI5_FIXED, DOPRI5_LIMIT)],
    ids=["rk4", "rk4-energy", "dopri5"],
)
@pytest.mark.parametrize("params", [TRAILER_FASTEST, CART_FASTEST], ids=["trailer", "cart"])
@pytest.mark.parametrize("speed", [0.5, 2.0])
def test_measured_limit_matches_theory(
    method: str, limit: float, params: ConvoyParams, speed: float
) -> None:
    """Largest stable h max|lambda| within 1% of x* (measured: within 0.03%), at two speeds."""
    assert largest_stable_step(method, params, speed) == pytest.approx(limit, rel=1e-2)


def test_linearisation_matches_the_kernel() -> None:
    """The Jacobian used for the theory equals finite differences of ``rhs`` (mass at rest)."""
    for params in (ConvoyParams(n_trailers=3), ConvoyParams(n_trailers=2, a=0.1, mu=0.0)):
        for speed in (0.7, -1.3):
            base = np.zeros(params.n_state)
            base[0] = speed
            step = 1e-7
            numeric = np.empty((params.n_state - 1, params.n_state - 1))
            for j in range(1, params.n_state):
                shift = np.zeros(params.n_state)
                shift[j] = step
                numeric[:, j - 1] = (rhs(params, base + shift) - rhs(params, base - shift))[1:] / (
                    2 * step
                )
            assert np.allclose(numeric, linearisation(params, speed), atol=1e-7)


def test_limit_with_the_mass_riding_on_the_cart() -> None:
    """n = 1, default parameters: the cart's rate (M a + mu b) / (I0 + mu b^2) binds."""
    params = ConvoyParams(n_trailers=1, l=2.0)
    cart, trailer = decay_rates(params, 1.0)
    assert cart > 2 * trailer
    assert largest_stable_step(RK4, params, 1.0) == pytest.approx(RK4_LIMIT, rel=1e-2)


@pytest.mark.parametrize("n", [2, 3, 8])
def test_jordan_block_lowers_the_practical_limit(n: int) -> None:
    """n trailers share one eigenvalue in one Jordan block: the matrix is not normal.

    The asymptotic limit is still x*, but a finite perturbation first grows like
    (K x)^(n-1) |R|^K before it decays, so with a bounded growth the largest usable
    step drops (measured x = 2.77, 2.66, 2.10 for n = 2, 3, 8, against 2.785 for n = 1).
    The linearised model stepped by the same tableau, under the same test, predicts it
    within 1% (measured: 0.15% for n = 2, exact for n = 3 and 8).
    """
    params = ConvoyParams(n_trailers=n, a=0.1, mu=0.0)
    measured = largest_stable_step(RK4, params, 1.0)
    predicted = largest_stable_step(RK4, params, 1.0, linear=True)
    assert measured == pytest.approx(predicted, rel=1e-2)
    assert measured < RK4_LIMIT
    if n >= 3:
        assert measured < RK4_LIMIT - 0.1


def _run_from_node(method: str, x: float) -> tuple[np.ndarray, float, float]:
    """The benchmark's 4000 steps of h = x l / |u| from the perturbed node, |u| = 1."""
    z, e0, h = run_from_node(method, TRAILER_FASTEST, x)
    return z[0], e0, h


def test_rk4_above_the_limit_bleeds_energy_back_under_it() -> None:
    """Plain RK4 beyond x*: the perturbation grows, energy is lost until h |u| / l < x*."""
    for x in (3.0, 4.0, 5.0):
        z, e0, h = _run_from_node(RK4, x)
        assert np.all(np.isfinite(z))
        assert float(energy(TRAILER_FASTEST, z)) / e0 < 0.9
        assert h * abs(z[0]) / TRAILER_FASTEST.l < RK4_LIMIT
        assert np.max(np.abs(rhs(TRAILER_FASTEST, z))) < 1e-8  # a true equilibrium, wrong energy


def test_rk4_blows_up_far_above_the_limit() -> None:
    z, _, _ = _run_from_node(RK4, 10.0)
    assert not np.all(np.isfinite(z)) or abs(z[0]) > 1e3


def test_energy_preserving_step_finds_a_spurious_equilibrium() -> None:
    """Just above x*, the energy-preserving step converges to a fixed point of the map
    that is not an equilibrium of the flow (alpha != 0, f != 0), with E exact."""
    params = TRAILER_FASTEST
    z, e0, h = _run_from_node(RK4_ENERGY_PRESERVING, 3.0)
    assert float(energy(params, z)) == pytest.approx(e0, rel=1e-12)
    assert abs(z[2]) > 0.1
    assert np.max(np.abs(rhs(params, z))) > 0.1
    once = z[None, :].copy()
    advance(RK4_ENERGY_PRESERVING, params, once, h, 1)
    assert np.max(np.abs(once[0] - z)) < 1e-12


def test_error_controlled_dopri5_rides_the_stability_boundary() -> None:
    """At the node the error estimate vanishes, the step grows to x* and is held there."""
    params = TRAILER_FASTEST
    z = perturbed_equilibrium(params, 1.0, 0.1)  # (u, omega, alpha_1) = (1, 0.1, 0.1)
    act = resting_mass_action(params)
    step = np.zeros(1)
    stepper = AdaptiveStepper(params, rtol=1e-6, atol=1e-6)
    stepper.step(z, act, 100.0, step)
    stats = stepper.step(z, act, 500.0, step)
    mean_x = 500.0 / stats.accepted[0] * abs(z[0, 0]) / params.l
    assert mean_x == pytest.approx(DOPRI5_LIMIT, rel=0.05)
    assert stats.rejected[0] > 0.05 * stats.accepted[0]  # it keeps probing past the boundary


@pytest.mark.parametrize("speed", [0.5, 2.0])
def test_predictability_horizon_on_the_reversing_node(speed: float) -> None:
    """Reversing, lambda = |u| / l > 0: a deviation eps reaches delta after ln(delta/eps)/lambda.

    RK4 with step h grows it by R(h lambda) per step instead of exp(h lambda): its
    horizon is ln(delta/eps) h / ln R(h lambda), 2.8% longer at h lambda = 2.
    """
    params = ConvoyParams(n_trailers=1, mu=0.0)
    epsilon, delta = 1e-10, 1e-2
    rate = speed / params.l
    exact = departure_time("exact", params, speed, epsilon, delta)
    assert exact == pytest.approx(math.log(delta / epsilon) / rate, rel=1e-2)
    for x in (1.0, 2.0):
        rk4 = departure_time(RK4, params, speed, epsilon, delta, x)
        assert rk4 == pytest.approx(
            math.log(delta / epsilon) * (x / rate) / math.log(rk4_stability(x).real), rel=1e-2
        )
    assert rk4 / exact == pytest.approx(2.0 / math.log(rk4_stability(2.0).real), rel=5e-3)


def test_stability_chart_command_runs(tmp_path: Path) -> None:
    """``python -m benchmarks.stability --quick`` (about 2 s) writes its CSVs and charts."""
    assert stability.main(["--quick", "--results", str(tmp_path), "--images", str(tmp_path)]) == 0
    for name in (
        "stability_limits.csv",
        "stability_failures.csv",
        "stability_horizon.csv",
        "stability_limits.png",
        "stability_failures.png",
    ):
        assert (tmp_path / name).stat().st_size > 0
