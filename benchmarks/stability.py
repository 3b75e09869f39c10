"""Where the integrators fail: stability limits, failure modes, predictability.

Run with ``python -m benchmarks.stability [--quick]``.

Theory. Linearised at the straight convoy moving at speed u (physics.md section 7),
the reduced state (u, omega, alpha_1..alpha_n) has the eigenvalues 0 (the energy
direction), lambda_0 = -(M a / I0) u (the cart's yaw) and lambda_k = -u / l
(k = 1..n, one Jordan block: alpha_k is driven by alpha_(k-1)). With
u = sigma_0 sqrt(2E/(M + n m)) these are the eigenvalues of section 7. A mass mu at
rest at (b, 0) on the cart is part of the cart: M a -> M a + mu b and
I0 -> I0 + mu b^2. A one-step method with stability function R(z) applied to the
linearisation multiplies each eigencomponent by R(h lambda) per step, so moving
forward (all lambda <= 0, real) it is stable iff

    x_trailer = h |u| / l  and  x_cart = h (M a + mu b) |u| / (I0 + mu b^2)

both lie in the method's interval of absolute stability on the negative real axis,
[0, x*): x* = 2.7853 for RK4 (R = 1 + z + z^2/2 + z^3/6 + z^4/24) and 3.3066 for
DOPRI5 (R from its tableau). The energy-preserving step rescales (u, omega) by
1 + O(perturbation^2), so it has RK4's linear limit. By the homogeneity of section 6
(time scales like 1/|u|) these dimensionless steps are all that matter.

Measured here:

* the largest stable dimensionless step of RK4, energy-preserving RK4 and fixed-step
  DOPRI5, by bisection (a perturbation of 1e-6 must decay), for convoys whose
  fastest eigenvalue is the trailers' or the cart's, at two speeds;
* what happens above the limit, over a sweep of x: RK4 dissipates energy until
  h |u| / l is back under x* (a true equilibrium at the wrong energy) and, further
  out, spins the trailers round or blows up; the energy-preserving step keeps E
  exactly but lands on spurious fixed points (alpha != 0 with f != 0), then spurious
  period-2 orbits, then wanders; error-controlled DOPRI5 does not fail: its steps
  settle on the stability boundary, h |lambda| ~ 3.3;
* the predictability horizon on the reversing (unstable) node: a deviation eps
  from the node grows like eps exp(lambda t) (lambda = |u| / l), so the time to
  reach Delta is ln(Delta / eps) / lambda (for n > 1 the Jordan block adds
  polynomial factors); RK4 with step h grows it by R(h lambda) per step instead,
  so its horizon is ln(Delta / eps) h / ln R(h lambda).

A run writes under ``--results``/``--images`` (default ``out/benchmarks/``); the
committed outputs: ``benchmarks/results/stability_limits.csv``, ``stability_failures.csv``,
``stability_horizon.csv``; ``docs/img/stability_limits.png`` and
``docs/img/stability_failures.png`` (drawn by :mod:`benchmarks.stability_plots`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import brentq

from benchmarks._common import one_thread, parse_command, report_written, write_csv
from benchmarks.stability_plots import plot_failures, plot_limits
from benchmarks.stability_theory import (
    DOPRI5_FIXED,
    METHODS,
    RK4,
    RK4_ENERGY_PRESERVING,
    real_axis_limit,
)
from dynamics import ConvoyParams, Stepper, energy, rhs
from dynamics.adaptive import DP_A, DP_B, AdaptiveStepper, integrate_adaptive

PERTURBATION = 1e-6


def decay_rates(params: ConvoyParams, speed: float) -> tuple[float, float]:
    """|lambda| of the cart's yaw and of the trailers at speed ``speed`` (mass at rest at s = 0)."""
    cart = (params.M * params.a + params.mu * params.b) / (params.I0 + params.mu * params.b**2)
    return abs(cart * speed), abs(speed) / params.l


def resting_mass_action(params: ConvoyParams) -> np.ndarray:
    """The steppers' action (1, 6) holding the moving mass at rest at (b, 0)."""
    return np.array([[params.b, 0.0, 0.0, 0.0, 0.0, 0.0]])


def advance(method: str, params: ConvoyParams, z: np.ndarray, h: float, steps: int) -> None:
    """Take ``steps`` fixed steps of size h in place (z: (1, n+2)); mass at rest at s = 0."""
    act = resting_mass_action(params)
    with np.errstate(all="ignore"):
        if method == DOPRI5_FIXED:
            # Tolerances no error can fail, steps capped at h: the fixed-step method.
            stepper = AdaptiveStepper(
                params, rtol=1e300, atol=1e300, max_step=h, max_steps=steps + 2
            )
            stepper.step(z, act, h * steps, np.full(1, h))
        else:
            stepper_rk4 = Stepper(params, preserve_energy=method == RK4_ENERGY_PRESERVING)
            stepper_rk4.step(z, act, h * steps, np.array([steps], dtype=np.int64))


CHUNK = 10
MAX_STEPS = 20_000
GROWTH_ALLOWED = 1e2
DECAY_REQUIRED = 1e-4


def perturbed_equilibrium(
    params: ConvoyParams, speed: float, size: float = PERTURBATION
) -> np.ndarray:
    """The straight convoy at speed ``speed``, every angle perturbed by ``size``.

    omega is perturbed by ``size |u| / l`` (a rate): by the homogeneity of physics.md
    section 6 the whole experiment then depends on h |u| only.
    """
    z = np.full((1, params.n_state), size)
    z[0, 0] = speed
    z[0, 1] = size * abs(speed) / params.l
    return z


def decays(method: str, params: ConvoyParams, speed: float, h: float) -> bool:
    """True when the perturbed forward node's deviation shrinks 1e4-fold within MAX_STEPS.

    Checked every CHUNK steps; the deviation may never exceed 100 times its start.
    Above the limit the perturbation can also grow, bleed the energy off nonlinearly
    and decay again at a lower speed within a chunk (see :func:`failure_outcome`):
    a change of the speed beyond the O(perturbation^2) of the linear regime also
    counts as unstable.
    """
    z = perturbed_equilibrium(params, speed)
    for _ in range(MAX_STEPS // CHUNK):
        advance(method, params, z, h, CHUNK)
        deviation = np.max(np.abs(z[0, 1:]))
        if not deviation <= GROWTH_ALLOWED * PERTURBATION or abs(z[0, 0] / speed - 1) > 1e-6:
            return False
        if deviation < DECAY_REQUIRED * PERTURBATION:
            return True
    return False


def linearisation(params: ConvoyParams, speed: float) -> np.ndarray:
    """Jacobian of (omega, alpha_1..alpha_n) at the straight convoy (section 7; u is constant)."""
    n = params.n_trailers
    cart, trailer = decay_rates(params, speed)
    sign = np.sign(speed)
    jacobian = np.zeros((n + 1, n + 1))
    jacobian[0, 0] = -cart * sign
    if n:
        jacobian[1, 0] = 1.0
        for k in range(1, n + 1):
            jacobian[k, k] = -trailer * sign
            if k > 1:
                jacobian[k, k - 1] = trailer * sign
    return jacobian


RK4_TABLEAU = (
    np.array([[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1.0, 0]]),
    np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6]),
)


def linear_propagator(method: str, jacobian: np.ndarray, h: float) -> np.ndarray:
    """The matrix of one step of the method on dv/dt = J v."""
    a, b = (DP_A[:6, :6], DP_B[:6]) if method == DOPRI5_FIXED else RK4_TABLEAU
    size = jacobian.shape[0]
    propagator = np.empty((size, size))
    for column in range(size):
        v = np.eye(size)[column]
        stages: list[np.ndarray] = []
        for i in range(len(b)):
            stages.append(jacobian @ (v + h * sum(a[i, j] * stages[j] for j in range(i))))
        propagator[:, column] = v + h * sum(b[i] * stages[i] for i in range(len(b)))
    return propagator


def decays_linear(method: str, params: ConvoyParams, speed: float, h: float) -> bool:
    """:func:`decays` on the linearisation: the theory for finite perturbations."""
    chunk = np.linalg.matrix_power(
        linear_propagator(method, linearisation(params, speed), h), CHUNK
    )
    v = perturbed_equilibrium(params, speed)[0, 1:]
    for _ in range(MAX_STEPS // CHUNK):
        v = chunk @ v
        deviation = np.max(np.abs(v))
        if not deviation <= GROWTH_ALLOWED * PERTURBATION:
            return False
        if deviation < DECAY_REQUIRED * PERTURBATION:
            return True
    return False


def largest_stable_step(
    method: str, params: ConvoyParams, speed: float, linear: bool = False
) -> float:
    """Bisection on h for the largest decaying step, returned as h * max |lambda|."""
    rate = max(decay_rates(params, speed))
    test = decays_linear if linear else decays
    low, high = 1.0 / rate, 5.0 / rate
    assert test(method, params, speed, low) and not test(method, params, speed, high)
    while high - low > 1e-4 * low:
        middle = 0.5 * (low + high)
        low, high = (middle, high) if test(method, params, speed, middle) else (low, middle)
    return 0.5 * (low + high) * rate


@dataclass(frozen=True)
class LimitCase:
    """A convoy whose fastest eigenvalue is the cart's or the trailers'."""

    label: str
    params: ConvoyParams
    dominant: str


LIMIT_CASES = (
    LimitCase(
        "n = 1, a = 0.1 (trailer fastest)", ConvoyParams(n_trailers=1, a=0.1, mu=0.0), "trailer"
    ),
    LimitCase("n = 1, l = 2 (cart fastest)", ConvoyParams(n_trailers=1, l=2.0, mu=0.0), "cart"),
    LimitCase("n = 3, default, mass at rest (cart)", ConvoyParams(n_trailers=3), "cart"),
    LimitCase(
        "n = 8, a = 0.1 (trailer, Jordan block)",
        ConvoyParams(n_trailers=8, a=0.1, mu=0.0),
        "trailer",
    ),
)


def measure_limits(quick: bool) -> list[dict[str, Any]]:
    """Measured largest stable dimensionless step against theory, per method and case."""
    rows = []
    cases = LIMIT_CASES[:2] if quick else LIMIT_CASES
    speeds = (1.0,) if quick else (0.5, 2.0)
    for method in METHODS:
        theory = real_axis_limit(method)
        for case in cases:
            for speed in speeds:
                cart, trailer = decay_rates(case.params, speed)
                measured = largest_stable_step(method, case.params, speed)
                linear = largest_stable_step(method, case.params, speed, linear=True)
                rows.append(
                    dict(
                        method=method,
                        case=case.label,
                        n=case.params.n_trailers,
                        speed=speed,
                        dominant=case.dominant,
                        cart_rate=cart,
                        trailer_rate=trailer,
                        largest_stable_h=measured / max(cart, trailer),
                        measured_x=measured,
                        theory_x=theory,
                        relative_gap=measured / theory - 1.0,
                        linear_model_x=linear,
                        gap_to_linear_model=measured / linear - 1.0,
                    )
                )
    return rows


FAILURE_PARAMS = ConvoyParams(n_trailers=1, a=0.1, mu=0.0)
"""Trailer-dominated (x = h |u| / l is the binding dimensionless step)."""


def run_from_node(
    method: str, params: ConvoyParams, x: float, steps: int = 4000
) -> tuple[np.ndarray, float, float]:
    """Run ``steps`` steps of h = x l / |u| from the perturbed forward node at |u| = 1.

    Returns:
        The final state (1, n+2), the initial energy and the step h.
    """
    speed = 1.0
    h = x * params.l / speed
    z = perturbed_equilibrium(params, speed)
    e0 = float(energy(params, z[0]))
    advance(method, params, z, h, steps)
    return z, e0, h


def failure_outcome(
    method: str, params: ConvoyParams, x: float, steps: int = 4000
) -> dict[str, Any]:
    """Run ``steps`` steps of h = x l / |u| from the perturbed forward node; classify the end."""
    speed = 1.0
    z, e0, h = run_from_node(method, params, x, steps)
    row: dict[str, Any] = dict(method=method, x=x)
    if not np.all(np.isfinite(z)) or abs(z[0, 0]) > 1e3 * speed:
        return row | dict(
            outcome="blow-up",
            energy_ratio=math.inf,
            final_x=math.inf,
            map_residual=math.nan,
            field_norm=math.nan,
        )
    once, twice = z.copy(), z.copy()
    advance(method, params, once, h, 1)
    advance(method, params, twice, h, 2)
    map_residual = float(np.max(np.abs(once - z)))
    period2_residual = float(np.max(np.abs(twice - z)))
    field_norm = float(np.max(np.abs(rhs(params, z[0]))))
    energy_ratio = float(energy(params, z[0])) / e0
    if field_norm < 1e-8:
        outcome = (
            "true equilibrium" if abs(energy_ratio - 1) < 1e-6 else "true equilibrium, energy lost"
        )
    elif map_residual < 1e-10:
        outcome = "spurious fixed point"
    elif period2_residual < 1e-10:
        outcome = "spurious period-2 orbit"
    else:
        outcome = "wandering"
    return row | dict(
        outcome=outcome,
        energy_ratio=energy_ratio,
        final_x=h * abs(z[0, 0]) / params.l,
        map_residual=map_residual,
        field_norm=field_norm,
    )


def measure_failures(quick: bool) -> list[dict[str, Any]]:
    """Outcome of each method over a sweep of the dimensionless step."""
    grid = np.round(np.arange(2.0, 10.0001, 0.5 if quick else 0.05), 4)
    return [failure_outcome(method, FAILURE_PARAMS, float(x)) for method in METHODS for x in grid]


def adaptive_steps(
    tolerance: float, params: ConvoyParams = FAILURE_PARAMS, duration: float = 300.0
) -> np.ndarray:
    """Dimensionless steps h |u| / l that error-controlled DOPRI5 takes at the forward node."""
    stepper = AdaptiveStepper(params, rtol=tolerance, atol=tolerance, max_step=math.inf)
    z = perturbed_equilibrium(params, 1.0, 0.1)
    act = resting_mass_action(params)
    step = np.zeros(1)
    x_values = []
    # One accepted or rejected step per call: unit max_steps, the carried step size
    # is what the controller proposes next.
    single = AdaptiveStepper(params, rtol=tolerance, atol=tolerance, max_steps=1)
    stepper.step(z, act, 20.0, step)  # settle at the node first
    for _ in range(int(duration)):
        trial = step.copy()
        stats = single.step(z, act, 1e9, step)
        if stats.accepted[0]:
            x_values.append(trial[0] * abs(z[0, 0]) / params.l)
    return np.array(x_values)


def departure_time(
    method: str, params: ConvoyParams, speed: float, epsilon: float, delta: float, x: float = 0.0
) -> float:
    """Time for max |alpha| to grow from epsilon to delta on the reversing node (omega = 0).

    ``method`` "exact" uses DOPRI5 at rtol 1e-12 sampled every 0.02 / lambda;
    "RK4" uses fixed steps h = x / lambda. Interpolates log |alpha| between samples.
    """
    rate = abs(speed) / params.l
    z = np.zeros((1, params.n_state))
    z[0, 0] = -abs(speed)
    z[0, 2] = epsilon
    sample = 0.02 / rate if method == "exact" else x / rate
    horizon = (math.log(delta / epsilon) + 10.0) / rate
    samples = int(horizon / sample) + 1
    if method == "exact":
        times = sample * np.arange(samples)
        result = integrate_adaptive(
            params, z[0], times[-1], rtol=1e-12, atol=1e-6 * epsilon, t_eval=times
        )
        assert result.z_samples is not None
        path = np.max(np.abs(result.z_samples[:, 2:]), axis=1)
    else:
        path = [float(np.max(np.abs(z[0, 2:])))]
        for _ in range(samples - 1):
            advance(RK4, params, z, sample, 1)
            path.append(float(np.max(np.abs(z[0, 2:]))))
        path = np.array(path)
    above = np.flatnonzero(path >= delta)
    if above.size == 0:
        return math.inf
    k = int(above[0])
    fraction = (math.log(delta) - math.log(path[k - 1])) / (
        math.log(path[k]) - math.log(path[k - 1])
    )
    return sample * (k - 1 + fraction)


def linear_departure_theory(n: int, rate: float, epsilon: float, delta: float) -> float:
    """Solve max_k eps exp(lambda t) (lambda t)^(k-1) / (k-1)! = delta (Jordan-block growth)."""

    def largest(t: float) -> float:
        s = rate * t
        return max(epsilon * math.exp(s) * s**k / math.factorial(k) for k in range(n))

    return float(brentq(lambda t: math.log(largest(t)) - math.log(delta), 0.0, 100.0 / rate))


def rk4_linear_departure(
    params: ConvoyParams, speed: float, epsilon: float, delta: float, x: float
) -> float:
    """RK4's departure time on the linearised reversing node, sampled and interpolated as measured.

    Per step the deviation is multiplied by the RK4 propagator of the Jordan block
    (R(x) = 1 + x + x^2/2 + x^3/6 + x^4/24 on the diagonal instead of exp(x)).
    """
    rate = abs(speed) / params.l
    h = x / rate
    propagator = linear_propagator(RK4, linearisation(params, -abs(speed)), h)
    v = np.zeros(params.n_trailers + 1)
    v[1] = epsilon
    previous = epsilon
    for k in range(1, 100_000):
        v = propagator @ v
        current = float(np.max(np.abs(v[1:])))
        if current >= delta:
            return h * (k - 1 + math.log(delta / previous) / math.log(current / previous))
        previous = current
    return math.inf


def measure_horizons(quick: bool) -> list[dict[str, Any]]:
    """Departure time from the reversing node against lambda, exact and RK4."""
    delta = 1e-2
    rows = []
    speeds = (0.5, 2.0) if quick else (0.25, 0.5, 1.0, 2.0, 4.0)
    epsilons = (1e-10,) if quick else (1e-14, 1e-10, 1e-6)
    for n in (1, 3):
        params = ConvoyParams(n_trailers=n, mu=0.0)
        for speed in speeds:
            rate = speed / params.l
            for epsilon in epsilons:
                theory = linear_departure_theory(n, rate, epsilon, delta)
                for method, x in (("exact", 0.0), (RK4, 1.0), (RK4, 2.0)):
                    if method == "exact":
                        predicted = theory
                    else:
                        predicted = rk4_linear_departure(params, speed, epsilon, delta, x)
                    measured = departure_time(method, params, speed, epsilon, delta, x)
                    rows.append(
                        dict(
                            n=n,
                            speed=speed,
                            rate=rate,
                            epsilon=epsilon,
                            delta=delta,
                            method=method,
                            x=x,
                            measured=measured,
                            predicted=predicted,
                            exact_theory=theory,
                        )
                    )
    return rows


def main(argv: list[str] | None = None) -> int:
    args = parse_command(
        "python -m benchmarks.stability", __doc__, "fewer cases and a coarse sweep", argv
    )
    start = time.perf_counter()
    with one_thread():
        limits = measure_limits(args.quick)
        write_csv(args.results / "stability_limits.csv", limits)
        for row in limits:
            print(
                f"{row['method']:22s} {row['case']:40s} |u| = {row['speed']:3.1f}: "
                f"x = {row['measured_x']:.4f} (theory {row['theory_x']:.4f}, "
                f"{100 * row['relative_gap']:+.2f}%)"
            )
        failures = measure_failures(args.quick)
        write_csv(args.results / "stability_failures.csv", failures)
        for method in METHODS:
            first: dict[str, float] = {}
            for row in failures:
                if row["method"] == method:
                    first.setdefault(row["outcome"], row["x"])
            print(
                f"{method:22s} first x of each outcome: "
                + ", ".join(f"{o} {x:.2f}" for o, x in first.items())
            )
        adaptive = {tolerance: adaptive_steps(tolerance) for tolerance in (1e-3, 1e-6)}
        for tolerance, values in adaptive.items():
            print(
                f"DOPRI5 rtol = atol = {tolerance:g} at the node: "
                f"mean h |u| / l = {np.mean(values):.3f}"
            )
        horizons = measure_horizons(args.quick)
        write_csv(args.results / "stability_horizon.csv", horizons)
        worst = max(abs(row["measured"] / row["predicted"] - 1) for row in horizons)
        print(f"departure times from the reversing node: worst gap to theory {100 * worst:.2f}%")
        plot_limits(limits, args.images / "stability_limits.png")
        plot_failures(failures, adaptive, horizons, args.images / "stability_failures.png")
    report_written(f"{args.results}/stability_*.csv and {args.images}/stability_*.png", start)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
