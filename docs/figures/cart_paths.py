"""The cart's paths, n = 1, a = 0: quasi-periodic, periodic, limiting circle (figure 3.7)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicHermiteSpline
from scipy.optimize import brentq

from docs.figures._common import (
    OMEGA0,
    ONE_TRAILER_A0,
    FloatArray,
    crossing_times,
    fit_circle,
    save_figure,
)
from dynamics import ConvoyParams, analysis, body_poses, inertia_R, rhs, simulate


@dataclass(frozen=True)
class CartPath:
    """A run of the one-trailer convoy with a = 0 and what is read off it."""

    params: ConvoyParams
    E: float
    omega0: float
    t: FloatArray
    z: FloatArray  # (time, 6): u, omega, alpha, x, y, theta
    period_read: float = math.nan  # E < E_c: mean time for alpha to gain 2 pi
    period_theory: float = math.nan  # analysis.period(E)
    period_poses: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))  # after k periods
    radius_read: float = math.nan  # E > E_c: circle fitted to the end of the path
    radius_theory: float = math.nan  # analysis.limiting_radius(E)
    centre: tuple[float, float] = (math.nan, math.nan)


def start_on_circle(params: ConvoyParams, E: float, omega0: float, alpha0: float) -> FloatArray:
    """Extended state on the invariant circle (3.37) of energy E at hitch angle alpha0."""
    u0 = math.sqrt((2.0 * E - params.J0 * omega0**2) / float(inertia_R(params, [alpha0])))
    return np.array([u0, omega0, alpha0, 0.0, 0.0, 0.0])


def run_on_circle(
    params: ConvoyParams, E: float, omega0: float, alpha0: float, t_end: float, dt: float
) -> tuple[FloatArray, FloatArray]:
    """Integrate from the circle of energy E; the energy rescaling keeps E exact."""
    run = simulate(
        params,
        start_on_circle(params, E, omega0, alpha0),
        dt,
        round(t_end / dt),
        substeps=2,
        preserve_energy=True,
    )
    return run.t, run.z


def periodic_orbit_data(
    params: ConvoyParams = ONE_TRAILER_A0,
    E: float = 0.45,
    omega0: float = OMEGA0,
    n_periods: int = 12,
    dt: float = 0.01,
) -> CartPath:
    """E < E_c: alpha turns round with period T(E); read T off the path and compare.

    The crossing times of alpha = 2 pi k are found on the Hermite spline of the samples
    and the exact rates ``rhs`` gives there, and T is their mean spacing. The cart's
    pose at those times is returned: after each period the cart has turned by omega0 T
    and moved, so the poses lie on a circle when the path is quasi-periodic.
    """
    T = analysis.period(params, E, omega0)
    t, z = run_on_circle(params, E, omega0, 0.0, (n_periods + 0.5) * T, dt)
    rates = rhs(params, z)
    levels = 2.0 * math.pi * np.arange(n_periods + 1, dtype=np.float64)
    crossings = crossing_times(t, z[:, 2], rates[:, 2], levels)
    # The pose at each crossing, to the same O(dt^4) accuracy.
    poses = np.stack(
        [CubicHermiteSpline(t, z[:, col], rates[:, col])(crossings) for col in (3, 4, 5)], axis=-1
    )
    return CartPath(
        params=params,
        E=E,
        omega0=omega0,
        t=t,
        z=z,
        period_read=float(np.mean(np.diff(crossings))),
        period_theory=T,
        period_poses=poses,
    )


def energy_for_rotation(
    params: ConvoyParams, rotation_turns: float, omega0: float = OMEGA0
) -> float:
    """The energy E < E_c at which the cart turns by ``rotation_turns`` * 2 pi per period.

    omega0 T(E) / (2 pi) rises from 1 at E = J0 omega0^2 / 2 to infinity at E_c; a rational
    value p / q with q > 1 makes the cart's path close after q periods.
    """
    E_low = 0.5 * params.J0 * omega0**2
    E_c = analysis.critical_energy(params, omega0)

    def excess(E: float) -> float:
        return omega0 * analysis.period(params, E, omega0) / (2.0 * math.pi) - rotation_turns

    return float(brentq(excess, E_low * (1 + 1e-9), E_c * (1 - 1e-6), xtol=1e-15, rtol=1e-14))


def limiting_circle_data(
    params: ConvoyParams = ONE_TRAILER_A0,
    E: float = 0.8,
    omega0: float = OMEGA0,
    alpha0: float = 2.2,
    t_end: float = 70.0,
    dt: float = 0.01,
    fit_from: float = 55.0,
) -> CartPath:
    """E > E_c: the cart tends to a circle; fit it to the end of the path and compare.

    Starting near the unstable relative equilibrium alpha(2), alpha slides to alpha(1) and
    the cart's path winds onto the circle of radius l / sin(alpha(1)).
    """
    t, z = run_on_circle(params, E, omega0, alpha0, t_end, dt)
    late = t >= fit_from
    centre_x, centre_y, radius = fit_circle(z[late, 3], z[late, 4])
    return CartPath(
        params=params,
        E=E,
        omega0=omega0,
        t=t,
        z=z,
        radius_read=radius,
        radius_theory=analysis.limiting_radius(params, E, omega0),
        centre=(centre_x, centre_y),
    )


@dataclass(frozen=True)
class CartPaths:
    """The three panels of thesis figure 3.7."""

    quasi_periodic: CartPath
    periodic: CartPath
    limiting: CartPath
    rotation_turns: tuple[int, int]  # p, q of the periodic path


def cart_paths_data(quick: bool = False) -> CartPaths:
    """Quasi-periodic (E < E_c), periodic (E < E_c, rational rotation) and E > E_c paths."""
    p, q = 5, 3
    periodic_E = energy_for_rotation(ONE_TRAILER_A0, p / q)
    dt = 0.02 if quick else 0.01
    return CartPaths(
        quasi_periodic=periodic_orbit_data(E=0.45, n_periods=4 if quick else 14, dt=dt),
        periodic=periodic_orbit_data(E=periodic_E, n_periods=q, dt=dt),
        limiting=limiting_circle_data(dt=dt),
        rotation_turns=(p, q),
    )


def draw_cart_paths(data: CartPaths, path: Path) -> None:
    """Three paths of the cart (and the trailer's in grey), as thesis figure 3.7."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13.0, 4.9))
    panels = (
        (data.quasi_periodic, "(a) E < E_c, quasi-periodic"),
        (data.periodic, "(b) E < E_c, periodic"),
        (data.limiting, "(c) E > E_c, tends to a circle"),
    )
    for ax, (run, name) in zip(axes, panels, strict=True):
        params = run.params
        x, y, theta = run.z[:, 3], run.z[:, 4], run.z[:, 5]
        trailer_x, trailer_y, _ = body_poses(params.l, x, y, theta, run.z[:, 2:3])
        ax.plot(trailer_x[:, 1], trailer_y[:, 1], color="0.75", lw=0.7, label="trailer")
        ax.plot(x, y, color="tab:blue", lw=1.0, label="cart")
        ax.plot(x[0], y[0], "s", color="black", ms=5, label="start")
        E_c = analysis.critical_energy(params, run.omega0)
        if run.period_poses.size:
            ax.plot(
                run.period_poses[:, 0],
                run.period_poses[:, 1],
                "o",
                color="tab:red",
                ms=4,
                label="after each period",
            )
            turns = run.omega0 * run.period_theory / (2.0 * math.pi)
            detail = (
                f"E = {run.E / E_c:.4f} E_c, ω0 T/2π = {turns:.6f}\n"
                f"T read off path {run.period_read:.8f}, T(E) {run.period_theory:.8f}"
            )
        else:
            circle = np.linspace(0.0, 2.0 * math.pi, 200)
            ax.plot(
                run.centre[0] + run.radius_theory * np.cos(circle),
                run.centre[1] + run.radius_theory * np.sin(circle),
                "--",
                color="tab:red",
                lw=1.5,
                label=r"$r = \ell/\sin\alpha^{(1)}$",
            )
            detail = (
                f"E = {run.E / E_c:.3f} E_c; radius read off path {run.radius_read:.8f},\n"
                rf"theory $\ell/\sin\alpha^{{(1)}}$ = {run.radius_theory:.8f}"
            )
        if run is data.periodic:
            p, q = data.rotation_turns
            detail = detail.replace("ω0 T/2π =", f"ω0 T/2π = {p}/{q} =", 1)
        ax.set_title(f"{name}\n{detail}", fontsize=8.5)
        ax.set_aspect("equal")
        ax.set_xlabel("x")
        ax.set_ylabel("y")
    axes[0].legend(fontsize=7, loc="upper right")
    axes[2].legend(fontsize=7, loc="upper right")
    fig.suptitle(
        "n = 1, a = 0, ω0 = 1: the cart's path in the plane, reconstructed from the reduced flow",
        fontsize=11,
    )
    save_figure(fig, path)
