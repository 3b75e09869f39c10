"""Measured stability limits of the integrators against linear stability theory.

How the dimensionless step maps to the eigenvalues. Linearised at the straight
convoy moving at speed u (physics.md section 6; here u = sigma_0 sqrt(2E/(M + n m)))
the reduced state (u, omega, alpha_1..alpha_n) has eigenvalues

    0 (along the energy),  lambda_0 = -(M a / I0) u,  lambda_k = -u / l  (k = 1..n).

A Runge-Kutta step of size h multiplies each eigencomponent by R(h lambda), R the
method's stability function, so going forward (lambda_k < 0) a perturbation decays
iff |R(-x)| < 1 for both dimensionless steps

    x_trailer = h |u| / l = h |lambda_k|,   x_cart = h M a |u| / I0 = h |lambda_0|,

that is iff max(x_trailer, x_cart) < x*, with x* = 2.7853 for RK4 and 3.3066 for
DOPRI5 (the roots of |R(-x)| = 1). By the homogeneity of section 5 (time scales
like 1/sqrt(E)), only these products matter: doubling |u| halves the largest stable h.
A mass mu at rest at (b, 0) rides with the cart: M a -> M a + mu b, I0 -> I0 + mu b^2.

The bisection below is independent of ``benchmarks/stability.py`` (which charts the
same quantities): it only uses the public steppers and the linear theory.
"""

from __future__ import annotations

import importlib
import math
import sys
from collections.abc import Iterator
from pathlib import Path

import numba
import numpy as np
import pytest
from scipy.optimize import brentq

from dynamics import ConvoyParams, Stepper, energy, rhs
from dynamics.adaptive import DP_A, DP_B, AdaptiveStepper, integrate_adaptive

PERTURBATION = 1e-6


def rk4_R(z: float) -> float:
    return 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24


def dopri5_R(z: float) -> float:
    """R(z) = 1 + z b^T (I - z A)^(-1) 1 over the six stages that build the solution."""
    a, b = DP_A[:6, :6], DP_B[:6]
    return float(1 + z * b @ np.linalg.solve(np.eye(6) - z * a, np.ones(6)))


@pytest.fixture(autouse=True, scope="module")
def _one_thread() -> Iterator[None]:
    """One-state runs gain nothing from the kernel's threads, whose spin-waits cost time."""
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    yield
    numba.set_num_threads(threads)


RK4_LIMIT = brentq(lambda x: abs(rk4_R(-x)) - 1, 2.0, 3.0, xtol=1e-14)
DOPRI5_LIMIT = brentq(lambda x: abs(dopri5_R(-x)) - 1, 3.0, 3.5, xtol=1e-14)


def _rates(params: ConvoyParams, speed: float) -> tuple[float, float]:
    """(|lambda_0|, |lambda_k|) with the mass at rest at (b, 0)."""
    cart = (params.M * params.a + params.mu * params.b) / (params.I0 + params.mu * params.b**2)
    return cart * abs(speed), abs(speed) / params.l


def _advance(method: str, params: ConvoyParams, z: np.ndarray, h: float, steps: int) -> None:
    act = np.array([[params.b, 0.0, 0.0, 0.0, 0.0, 0.0]])
    with np.errstate(all="ignore"):
        if method == "dopri5":
            stepper = AdaptiveStepper(
                params, rtol=1e300, atol=1e300, max_step=h, max_steps=steps + 2
            )
            stepper.step(z, act, h * steps, np.full(1, h))
        else:
            rk4 = Stepper(params, preserve_energy=method == "rk4-energy")
            rk4.step(z, act, h * steps, np.array([steps], dtype=np.int64))


CHUNK = 10  # steps between checks
MAX_STEPS = 20_000
GROWTH_ALLOWED = 1e2
DECAY_REQUIRED = 1e-4


def _perturbed_node(params: ConvoyParams, speed: float) -> np.ndarray:
    """Angles perturbed by 1e-6, omega by 1e-6 |u| / l: homogeneous, so only h |u| matters."""
    z = np.full((1, params.n_state), PERTURBATION)
    z[0, 0] = speed
    z[0, 1] = PERTURBATION * abs(speed) / params.l
    return z


def _decays(method: str, params: ConvoyParams, speed: float, h: float) -> bool:
    """A 1e-6 perturbation of every angle and omega shrinks 1e4-fold, never growing 100-fold.

    Checked every CHUNK steps. Unstable steps can also grow the perturbation, bleed
    energy and decay again at a lower speed within a chunk: a change of the speed
    beyond the O(perturbation^2) of the linear regime also counts as unstable.
    """
    z = _perturbed_node(params, speed)
    for _ in range(MAX_STEPS // CHUNK):
        _advance(method, params, z, h, CHUNK)
        deviation = np.max(np.abs(z[0, 1:]))
        if not deviation <= GROWTH_ALLOWED * PERTURBATION or abs(z[0, 0] / speed - 1) > 1e-6:
            return False
        if deviation < DECAY_REQUIRED * PERTURBATION:
            return True
    return False


def _linearisation(params: ConvoyParams, speed: float) -> np.ndarray:
    """Jacobian of (omega, alpha_1..alpha_n) at the straight convoy (u is constant to first order).

    Written from physics.md sections 3-4 and 6, independently of the kernel (and
    checked against finite differences of ``rhs`` below).
    """
    n = params.n_trailers
    cart, trailer = _rates(params, speed)
    jacobian = np.zeros((n + 1, n + 1))
    jacobian[0, 0] = -cart * np.sign(speed)
    if n:
        jacobian[1, 0] = 1.0
        for k in range(1, n + 1):
            jacobian[k, k] = -trailer * np.sign(speed)
            if k > 1:
                jacobian[k, k - 1] = trailer * np.sign(speed)
    return jacobian


RK4_TABLEAU = (
    np.array([[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1.0, 0]]),
    np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6]),
)


def _decays_linear(method: str, params: ConvoyParams, speed: float, h: float) -> bool:
    """The same test on the linearisation, stepped by the method's tableau: the theory."""
    a, b = (DP_A[:6, :6], DP_B[:6]) if method == "dopri5" else RK4_TABLEAU
    jacobian = _linearisation(params, speed)
    size = jacobian.shape[0]
    # One step of a linear RK method is a matrix: v <- P v.
    propagator = np.empty((size, size))
    for column in range(size):
        v = np.eye(size)[column]
        stages: list[np.ndarray] = []
        for i in range(len(b)):
            stages.append(jacobian @ (v + h * sum(a[i, j] * stages[j] for j in range(i))))
        propagator[:, column] = v + h * sum(b[i] * stages[i] for i in range(len(b)))
    chunk = np.linalg.matrix_power(propagator, CHUNK)
    v = _perturbed_node(params, speed)[0, 1:]
    for _ in range(MAX_STEPS // CHUNK):
        v = chunk @ v
        deviation = np.max(np.abs(v))
        if not deviation <= GROWTH_ALLOWED * PERTURBATION:
            return False
        if deviation < DECAY_REQUIRED * PERTURBATION:
            return True
    return False


def _largest_stable_x(
    method: str, params: ConvoyParams, speed: float, linear: bool = False
) -> float:
    """Bisection for the largest decaying h, returned as h * max |lambda|."""
    rate = max(_rates(params, speed))
    test = _decays_linear if linear else _decays
    low, high = 1.0 / rate, 5.0 / rate
    assert test(method, params, speed, low) and not test(method, params, speed, high)
    while high - low > 1e-4 * low:
        middle = 0.5 * (low + high)
        low, high = (middle, high) if test(method, params, speed, middle) else (low, middle)
    return 0.5 * (low + high) * rate


def test_theoretical_limits() -> None:
    """Literature values: RK4 2.7853 (Hairer and Wanner IV.2), DOPRI5 3.3066."""
    assert abs(RK4_LIMIT - 2.785293563) < 1e-8
    assert abs(DOPRI5_LIMIT - 3.3066) < 1e-4


TRAILER_FASTEST = ConvoyParams(n_trailers=1, a=0.1, mu=0.0)  # M a / I0 = 0.48 < 1 / l = 1
CART_FASTEST = ConvoyParams(n_trailers=1, l=2.0, mu=0.0)  # M a / I0 = 1.11 > 1 / l = 0.5


@pytest.mark.parametrize(
    ("method", "limit"), [("rk4", RK4_LIMIT), ("rk4-energy", RK4_LIMIT), ("dopri5", DOPRI5_LIMIT)]
)
@pytest.mark.parametrize("params", [TRAILER_FASTEST, CART_FASTEST], ids=["trailer", "cart"])
@pytest.mark.parametrize("speed", [0.5, 2.0])
def test_measured_limit_matches_theory(
    method: str, limit: float, params: ConvoyParams, speed: float
) -> None:
    """Largest stable h max|lambda| within 1% of x* (measured: within 0.03%), at two speeds."""
    assert _largest_stable_x(method, params, speed) == pytest.approx(limit, rel=1e-2)


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
            assert np.allclose(numeric, _linearisation(params, speed), atol=1e-7)


def test_limit_with_the_mass_riding_on_the_cart() -> None:
    """n = 1, default parameters: the cart's rate (M a + mu b) / (I0 + mu b^2) binds."""
    params = ConvoyParams(n_trailers=1, l=2.0)
    cart, trailer = _rates(params, 1.0)
    assert cart > 2 * trailer
    assert _largest_stable_x("rk4", params, 1.0) == pytest.approx(RK4_LIMIT, rel=1e-2)


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
    measured = _largest_stable_x("rk4", params, 1.0)
    predicted = _largest_stable_x("rk4", params, 1.0, linear=True)
    assert measured == pytest.approx(predicted, rel=1e-2)
    assert measured < RK4_LIMIT
    if n >= 3:
        assert measured < RK4_LIMIT - 0.1


def _run_from_node(method: str, x: float, steps: int = 4000) -> tuple[np.ndarray, float, float]:
    params = TRAILER_FASTEST
    z = np.full((1, params.n_state), PERTURBATION)
    z[0, 0] = 1.0
    e0 = float(energy(params, z[0]))
    _advance(method, params, z, x * params.l, steps)
    return z[0], e0, x * params.l


def test_rk4_above_the_limit_bleeds_energy_back_under_it() -> None:
    """Plain RK4 beyond x*: the perturbation grows, energy is lost until h |u| / l < x*."""
    for x in (3.0, 4.0, 5.0):
        z, e0, h = _run_from_node("rk4", x)
        assert np.all(np.isfinite(z))
        assert float(energy(TRAILER_FASTEST, z)) / e0 < 0.9
        assert h * abs(z[0]) / TRAILER_FASTEST.l < RK4_LIMIT
        assert np.max(np.abs(rhs(TRAILER_FASTEST, z))) < 1e-8  # a true equilibrium, wrong energy


def test_rk4_blows_up_far_above_the_limit() -> None:
    z, _, _ = _run_from_node("rk4", 10.0)
    assert not np.all(np.isfinite(z)) or abs(z[0]) > 1e3


def test_energy_preserving_step_finds_a_spurious_equilibrium() -> None:
    """Just above x*, the energy-preserving step converges to a fixed point of the map
    that is not an equilibrium of the flow (alpha != 0, f != 0), with E exact."""
    params = TRAILER_FASTEST
    z, e0, h = _run_from_node("rk4-energy", 3.0)
    assert float(energy(params, z)) == pytest.approx(e0, rel=1e-12)
    assert abs(z[2]) > 0.1
    assert np.max(np.abs(rhs(params, z))) > 0.1
    once = z[None, :].copy()
    _advance("rk4-energy", params, once, h, 1)
    assert np.max(np.abs(once[0] - z)) < 1e-12


def test_error_controlled_dopri5_rides_the_stability_boundary() -> None:
    """At the node the error estimate vanishes, the step grows to x* and is held there."""
    params = TRAILER_FASTEST
    z = np.array([[1.0, 0.1, 0.1]])
    act = np.array([[params.b, 0.0, 0.0, 0.0, 0.0, 0.0]])
    step = np.zeros(1)
    stepper = AdaptiveStepper(params, rtol=1e-6, atol=1e-6)
    stepper.step(z, act, 100.0, step)
    stats = stepper.step(z, act, 500.0, step)
    mean_x = 500.0 / stats.accepted[0] * abs(z[0, 0]) / params.l
    assert mean_x == pytest.approx(DOPRI5_LIMIT, rel=0.05)
    assert stats.rejected[0] > 0.05 * stats.accepted[0]  # it keeps probing past the boundary


def _departure_time(
    params: ConvoyParams, speed: float, epsilon: float, delta: float, h: float | None
) -> float:
    """Time for alpha to grow from epsilon to delta on the reversing node (log-interpolated)."""
    rate = speed / params.l
    sample = h if h is not None else 0.01 / rate
    count = int((math.log(delta / epsilon) + 5.0) / rate / sample) + 1
    z0 = np.zeros(params.n_state)
    z0[0], z0[2] = -speed, epsilon
    if h is None:
        times = sample * np.arange(count)
        result = integrate_adaptive(
            params, z0, times[-1], rtol=1e-12, atol=1e-6 * epsilon, t_eval=times
        )
        assert result.z_samples is not None
        path = np.abs(result.z_samples[:, 2])
    else:
        z = z0[None, :].copy()
        values = [epsilon]
        for _ in range(count - 1):
            _advance("rk4", params, z, h, 1)
            values.append(abs(z[0, 2]))
        path = np.array(values)
    k = int(np.flatnonzero(path >= delta)[0])
    fraction = math.log(delta / path[k - 1]) / math.log(path[k] / path[k - 1])
    return sample * (k - 1 + fraction)


@pytest.mark.parametrize("speed", [0.5, 2.0])
def test_predictability_horizon_on_the_reversing_node(speed: float) -> None:
    """Reversing, lambda = |u| / l > 0: a deviation eps reaches delta after ln(delta/eps)/lambda.

    RK4 with step h grows it by R(h lambda) per step instead of exp(h lambda): its
    horizon is ln(delta/eps) h / ln R(h lambda), 2.8% longer at h lambda = 2.
    """
    params = ConvoyParams(n_trailers=1, mu=0.0)
    epsilon, delta = 1e-10, 1e-2
    rate = speed / params.l
    exact = _departure_time(params, speed, epsilon, delta, None)
    assert exact == pytest.approx(math.log(delta / epsilon) / rate, rel=1e-2)
    for x in (1.0, 2.0):
        rk4 = _departure_time(params, speed, epsilon, delta, x / rate)
        assert rk4 == pytest.approx(
            math.log(delta / epsilon) * (x / rate) / math.log(rk4_R(x)), rel=1e-2
        )
    assert rk4 / exact == pytest.approx(2.0 / math.log(rk4_R(2.0)), rel=5e-3)


def test_stability_chart_command_runs(tmp_path: Path) -> None:
    """``python -m benchmarks.stability --quick`` (about 2 s) writes its CSVs and charts."""
    root = Path(__file__).resolve().parents[2]
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    stability = importlib.import_module("benchmarks.stability")
    assert stability.main(["--quick", "--results", str(tmp_path), "--images", str(tmp_path)]) == 0
    for name in (
        "stability_limits.csv",
        "stability_failures.csv",
        "stability_horizon.csv",
        "stability_limits.png",
        "stability_failures.png",
    ):
        assert (tmp_path / name).stat().st_size > 0
