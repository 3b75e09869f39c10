"""Draw the thesis's pictures from the project's own ``dynamics``, with the numbers behind them.

Run from the repository root (20 to 40 s; ``--quick`` draws coarser pictures in under 10 s)::

    python docs/make_figures.py [--out docs/img] [--quick]

It writes ``thesis_*.png`` (chapter 3 and appendix A of the thesis in ``docs/physics.md``):

* ``thesis_torus_portrait.png``: the flow on the energy torus (alpha_1, beta), n = 1, a > 0;
* ``thesis_straight_line.png``: the cart's path straightening out, a > 0;
* ``thesis_level_function.png``: f(alpha) = sin^2(alpha)/R(alpha) and energy levels, n = 1, a = 0;
* ``thesis_invariant_circles.png``: the invariant circles and the cylinder omega = omega_0;
* ``thesis_cart_paths.png``: quasi-periodic, periodic and limiting-circle paths of the cart;
* ``thesis_singular_set.png``: the degree of nonholonomy over the hitch-angle torus, n = 2, 3.

Every picture has a pure function computing its numbers (``*_data`` and a few helpers),
which ``tests/docs/test_figures.py`` checks, and a function drawing them (``draw_*``). All
physics comes from ``dynamics``: this file only samples, integrates, interpolates and fits.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicHermiteSpline
from scipy.optimize import brentq

from dynamics import (
    ConvoyParams,
    analysis,
    body_poses,
    inertia_R,
    rhs,
    simulate,
    singular_margin,
)
from dynamics.nonholonomy import nonholonomy_degree

if TYPE_CHECKING:
    from matplotlib.figure import Figure

FloatArray = NDArray[np.float64]

# The house convoy without its actuator: the thesis studies the convoy moving by inertia.
ONE_TRAILER = ConvoyParams(n_trailers=1, mu=0.0)
"""n = 1, a = 0.5 (centre of mass ahead of the axle): the straight convoy is stable."""
ONE_TRAILER_A0 = ONE_TRAILER.replace(a=0.0)
"""n = 1, a = 0: omega is conserved (thesis section 3.4)."""
OMEGA0 = 1.0
"""Angular velocity of the cart in the a = 0 pictures; E_c = 0.65 for ONE_TRAILER_A0."""

# Window of the torus pictures: all four n = 1 equilibria lie inside it, none on its edges.
TORUS_WINDOW = (-0.5 * math.pi, 1.5 * math.pi)

KIND_STYLE = {
    "stable node": {"color": "tab:green", "marker": "o"},
    "unstable node": {"color": "tab:red", "marker": "o"},
    "saddle": {"color": "tab:orange", "marker": "X"},
}


# ----------------------------------------------------------------------------------------
# Generic helpers: wrapping, crossing times, fits, saving
# ----------------------------------------------------------------------------------------


def wrap_into(angles: FloatArray, window: tuple[float, float] = TORUS_WINDOW) -> FloatArray:
    """Angles shifted by multiples of 2 pi into ``[window[0], window[0] + 2 pi)``."""
    low = window[0]
    return np.asarray(low + np.mod(np.asarray(angles) - low, 2.0 * math.pi))


def break_at_jumps(*coordinates: FloatArray, jump: float = math.pi) -> list[FloatArray]:
    """Insert NaN between samples where any coordinate jumps (a wrap), so lines are not drawn.

    Returns:
        The coordinates with NaNs inserted at the same places.
    """
    stacked = np.stack(coordinates)
    jumps = np.any(np.abs(np.diff(stacked, axis=1)) > jump, axis=0)
    cut_after = np.flatnonzero(jumps) + 1
    return [np.insert(c.astype(float), cut_after, np.nan) for c in coordinates]


def crossing_times(
    t: FloatArray, values: FloatArray, rates: FloatArray, levels: FloatArray
) -> FloatArray:
    """Times at which a sampled increasing signal crosses each level.

    The signal is interpolated by the cubic Hermite spline through the samples and their
    exact time derivatives (from ``rhs``), so the error is O(dt^4) like the RK4 samples'.

    Args:
        t: Sample times, increasing.
        values: The signal at ``t`` (increasing through the levels).
        rates: Its time derivative at ``t``.
        levels: Levels to cross.

    Returns:
        The first crossing time of each level (NaN where the level is not reached).
    """
    spline = CubicHermiteSpline(t, values, rates)
    found = []
    for level in np.asarray(levels, dtype=float):
        roots = spline.solve(level, extrapolate=False)
        found.append(float(roots[0]) if roots.size else math.nan)
    return np.array(found)


def fit_decay_rate(t: FloatArray, values: FloatArray) -> float:
    """Slope of log|values| against t by least squares: the exponential rate of decay."""
    slope, _ = np.polyfit(t, np.log(np.abs(values)), 1)
    return float(slope)


def fit_circle(x: FloatArray, y: FloatArray) -> tuple[float, float, float]:
    """Least-squares circle through points (Kasa's algebraic fit): centre and radius.

    Exact when the points lie on a circle, which is how the tests use it.
    """
    design = np.column_stack([x, y, np.ones_like(x)])
    target = x * x + y * y
    (c0, c1, c2), *_ = np.linalg.lstsq(design, target, rcond=None)
    centre_x, centre_y = 0.5 * c0, 0.5 * c1
    return float(centre_x), float(centre_y), float(math.sqrt(c2 + centre_x**2 + centre_y**2))


def save_figure(fig: Figure, path: Path) -> None:
    """Lay out, write (100 dpi) and close a figure."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


# ----------------------------------------------------------------------------------------
# 1. The energy torus for n = 1, a > 0 (thesis figure 3.2a)
# ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TorusPoint:
    """An equilibrium drawn on the torus (angles wrapped into TORUS_WINDOW)."""

    alpha: float
    beta: float
    kind: str
    z: FloatArray
    eigenvalues: FloatArray


@dataclass(frozen=True)
class TorusPortrait:
    """The flow on one energy torus of the one-trailer convoy."""

    params: ConvoyParams
    E: float
    alpha: FloatArray  # grid (columns)
    beta: FloatArray  # grid (rows)
    alpha_dot: FloatArray  # (beta, alpha)
    beta_dot: FloatArray
    equilibria: list[TorusPoint]
    paths: list[tuple[FloatArray, FloatArray]]  # (alpha(t), beta(t)), wrapped
    path_energy: list[FloatArray]  # E along each path, to check it stays on the torus


def torus_equilibria(params: ConvoyParams, E: float) -> list[TorusPoint]:
    """The 2^(n+1) equilibria of ``dynamics.analysis`` as points of the torus (n = 1)."""
    points = []
    for eq in analysis.equilibria(params, E):
        _, beta, alpha = analysis.to_torus(params, eq.z)
        points.append(
            TorusPoint(
                alpha=float(wrap_into(alpha[0])),
                beta=float(wrap_into(beta)),
                kind=eq.kind,
                z=np.asarray(eq.z),
                eigenvalues=np.asarray(eq.eigenvalues),
            )
        )
    return points


def torus_linearisation(
    params: ConvoyParams, E: float, beta: float, alpha: Sequence[float], step: float = 1e-6
) -> FloatArray:
    """Jacobian of the torus field (beta_dot, alpha_dot) in (beta, alpha), central differences.

    Independent of the closed-form eigenvalues of ``analysis.equilibria``, so the tests can
    compare the two.
    """
    point = np.concatenate([[beta], np.asarray(alpha, dtype=float)])
    size = point.size
    jac = np.empty((size, size))
    for j in range(size):
        shift = np.zeros(size)
        shift[j] = step
        columns = []
        for sign in (1.0, -1.0):
            moved = point + sign * shift
            beta_dot, alpha_dot = analysis.torus_field(params, E, moved[0], moved[1:])
            columns.append(np.concatenate([[float(beta_dot)], alpha_dot]))
        jac[:, j] = (columns[0] - columns[1]) / (2.0 * step)
    return jac


def torus_portrait_data(
    params: ConvoyParams = ONE_TRAILER,
    E: float = 0.5,
    grid_size: int = 41,
    starts: Sequence[tuple[float, float]] = (
        (0.05, math.pi - 0.05),
        (-0.05, math.pi + 0.05),
        (0.2, math.pi + 0.01),
        (-0.2, math.pi - 0.01),
        (math.pi - 0.01, 0.5),
        (math.pi + 0.01, -0.5),
    ),
    t_end: float = 25.0,
    dt: float = 0.02,
) -> TorusPortrait:
    """Sample the torus field on a grid and integrate a few orbits with ``simulate``.

    Args:
        params: A one-trailer convoy with a != 0.
        E: Energy level (the picture is the same for every E > 0 up to a time scale).
        grid_size: Grid points per angle.
        starts: Initial (alpha_1, beta) of the drawn orbits.
        t_end, dt: Length and sampling of the orbits.
    """
    grid = np.linspace(*TORUS_WINDOW, grid_size)
    alpha_grid, beta_grid = np.meshgrid(grid, grid)
    beta_dot, alpha_dot = analysis.torus_field(params, E, beta_grid, alpha_grid[..., None])
    paths, energies = [], []
    free = analysis.free_params(params)
    for alpha0, beta0 in starts:
        z0 = analysis.from_torus(free, E, beta0, [alpha0])
        run = simulate(free, z0, dt, round(t_end / dt), substeps=2)
        energy_along, beta, alpha = analysis.to_torus(free, run.z)
        paths.append((wrap_into(alpha[:, 0]), wrap_into(beta)))
        energies.append(energy_along)
    return TorusPortrait(
        params=params,
        E=E,
        alpha=grid,
        beta=grid,
        alpha_dot=alpha_dot[..., 0],
        beta_dot=beta_dot,
        equilibria=torus_equilibria(params, E),
        paths=paths,
        path_energy=energies,
    )


def draw_torus_portrait(data: TorusPortrait, path: Path) -> None:
    """Phase portrait on the torus with the four equilibria, as thesis figure 3.2(a)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 5.6))
    ax.streamplot(
        data.alpha,
        data.beta,
        data.alpha_dot,
        data.beta_dot,
        color="0.7",
        density=1.2,
        linewidth=0.8,
        arrowsize=0.9,
    )
    for number, (alpha, beta) in enumerate(data.paths):
        a_line, b_line = break_at_jumps(alpha, beta)
        label = "orbits computed with simulate" if number == 0 else None
        ax.plot(a_line, b_line, color="tab:blue", lw=1.8, label=label)
        middle = alpha.size // 8
        ax.annotate(
            "",
            xy=(alpha[middle + 1], beta[middle + 1]),
            xytext=(alpha[middle], beta[middle]),
            arrowprops={"arrowstyle": "-|>", "color": "tab:blue", "lw": 1.8},
        )
    shown: set[str] = set()
    for point in data.equilibria:
        style = KIND_STYLE[point.kind]
        label = None if point.kind in shown else point.kind
        shown.add(point.kind)
        ax.plot(
            point.alpha,
            point.beta,
            ls="none",
            ms=11,
            mec="black",
            label=label,
            color=style["color"],
            marker=style["marker"],
        )
    ticks = np.arange(-0.5, 1.51, 0.5) * math.pi
    names = [r"$-\pi/2$", "0", r"$\pi/2$", r"$\pi$", r"$3\pi/2$"]
    ax.set_xticks(ticks, names)
    ax.set_yticks(ticks, names)
    ax.set_xlim(*TORUS_WINDOW)
    ax.set_ylim(*TORUS_WINDOW)
    ax.set_xlabel(r"hitch angle $\alpha_1$")
    ax.set_ylabel(r"torus angle $\beta$  ($u \propto \cos\beta$, $\omega \propto \sin\beta$)")
    p = data.params
    ax.set_title(
        "n = 1, a > 0: generic orbits run from the unstable node (convoy reversing)\n"
        "to the stable node (straight convoy going forward)\n"
        f"M={p.M:g}, J0={p.J0:g}, a={p.a:g}, m={p.m:g}, "
        f"J={p.J:g}, l={p.l:g}, E={data.E:g}",
        fontsize=9,
    )
    ax.legend(loc="upper right", fontsize=8, framealpha=0.9)
    save_figure(fig, path)


# ----------------------------------------------------------------------------------------
# 2. The cart's path straightens out, a > 0 (thesis figure 3.2b)
# ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class StraightLine:
    """A run of the free convoy from a turning start, with the decay rates read off it."""

    params: ConvoyParams
    E: float
    t: FloatArray
    z: FloatArray  # (time, n+5): u, omega, alphas, x, y, theta
    curvature: FloatArray  # omega / u: the curvature of the cart's path
    fit_window: tuple[float, float]
    curvature_rate: float  # fitted slope of log|curvature|
    hitch_rate: float  # fitted slope of log|alpha_1|
    lambda_0: float  # predicted by dynamics.analysis (stable node)
    lambda_1: float


def straight_line_data(
    params: ConvoyParams = ONE_TRAILER,
    E: float = 0.5,
    beta0: float = 0.7,
    alpha0: float = 0.6,
    t_end: float = 40.0,
    dt: float = 0.01,
    fit_window: tuple[float, float] = (25.0, 40.0),
) -> StraightLine:
    """Integrate the convoy from a sharp turn and fit the exponential decay of the turn.

    Near the stable node omega_dot = -(M a / I0) u omega with u -> sqrt(2E/(M + n m)), so
    the curvature omega / u of the cart's path decays like exp(lambda_0 t), and the hitch
    angles like exp(lambda_1 t) (the slower of lambda_0 and lambda_1 wins for them).
    """
    free = analysis.free_params(params)
    n = free.n_trailers
    start = analysis.from_torus(free, E, beta0, np.full(n, alpha0))
    z0 = np.concatenate([start, [0.0, 0.0, 0.0]])
    run = simulate(free, z0, dt, round(t_end / dt), substeps=2)
    curvature = run.z[:, 1] / run.z[:, 0]
    late = (run.t >= fit_window[0]) & (run.t <= fit_window[1])
    stable = next(eq for eq in analysis.equilibria(free, E) if eq.kind == "stable node")
    return StraightLine(
        params=free,
        E=E,
        t=run.t,
        z=run.z,
        curvature=curvature,
        fit_window=fit_window,
        curvature_rate=fit_decay_rate(run.t[late], curvature[late]),
        hitch_rate=fit_decay_rate(run.t[late], run.z[late, 2]) if n else math.nan,
        lambda_0=float(stable.eigenvalues[0]),
        lambda_1=float(stable.eigenvalues[1]) if n else math.nan,
    )


def draw_convoy(ax: object, params: ConvoyParams, row: FloatArray, color: str) -> None:
    """Draw the convoy of one extended state: rods, axles and the cart's heading."""
    n = params.n_trailers
    xs, ys, thetas = body_poses(params.l, row[n + 2], row[n + 3], row[n + 4], row[2 : n + 2])
    half_axle = 0.15 * params.l
    ax.plot(xs, ys, "-", color=color, lw=1.5)  # type: ignore[attr-defined]
    for x, y, theta in zip(xs, ys, thetas, strict=True):
        ax.plot(  # type: ignore[attr-defined]
            [x - half_axle * math.sin(theta), x + half_axle * math.sin(theta)],
            [y + half_axle * math.cos(theta), y - half_axle * math.cos(theta)],
            color=color,
            lw=2.5,
        )
    nose = 0.35 * params.l
    ax.annotate(  # type: ignore[attr-defined]
        "",
        xy=(xs[0] + nose * math.cos(thetas[0]), ys[0] + nose * math.sin(thetas[0])),
        xytext=(xs[0], ys[0]),
        arrowprops={"arrowstyle": "->", "color": color, "lw": 1.5},
    )


def rotated_poses(params: ConvoyParams, z: FloatArray, angle: float) -> FloatArray:
    """Extended states with the plane turned by ``angle`` about the origin (an SE(2) symmetry)."""
    n = params.n_trailers
    turned = z.copy()
    c, s = math.cos(angle), math.sin(angle)
    turned[:, n + 2] = c * z[:, n + 2] - s * z[:, n + 3]
    turned[:, n + 3] = s * z[:, n + 2] + c * z[:, n + 3]
    turned[:, n + 4] = z[:, n + 4] + angle
    return turned


def draw_straight_line(data: StraightLine, path: Path, shown_until: float = 14.0) -> None:
    """The cart's path with snapshots of the convoy, and the decay of its curvature."""
    import matplotlib.pyplot as plt

    n = data.params.n_trailers
    fig, (ax_path, ax_rate) = plt.subplots(
        2, 1, figsize=(9.0, 8.0), gridspec_kw={"height_ratios": (1.0, 1.2)}
    )
    # Turn the plane so that the limiting line is horizontal (the dynamics are SE(2)-invariant).
    shown = data.t <= shown_until
    z = rotated_poses(data.params, data.z[shown], -float(data.z[-1, n + 4]))
    x, y = z[:, n + 2], z[:, n + 3]
    trailer_x, trailer_y, _ = body_poses(data.params.l, x, y, z[:, n + 4], z[:, 2 : n + 2])
    ax_path.plot(x, y, color="tab:blue", lw=2, label="cart (axle midpoint)")
    ax_path.plot(trailer_x[:, -1], trailer_y[:, -1], color="tab:gray", lw=1, label="trailer")
    for time_mark in (0.0, 2.5, 5.0, 8.0, shown_until):
        index = int(np.argmin(np.abs(data.t[shown] - time_mark)))
        draw_convoy(ax_path, data.params, z[index], "black")
        ax_path.annotate(
            f"t={time_mark:g}", (x[index], y[index]), textcoords="offset points", xytext=(-6, 12)
        )
    ax_path.axhline(y[-1], color="tab:red", ls=":", lw=1, label="limiting line")
    ax_path.set_aspect("equal")
    ax_path.margins(0.06, 0.25)
    ax_path.set_xlabel("x (along the limiting line)")
    ax_path.set_ylabel("y")
    ax_path.set_title(
        "the cart swerves, its trailer follows, and the path straightens out", fontsize=10
    )
    ax_path.legend(fontsize=8, loc="upper right")

    ax_rate.semilogy(
        data.t, np.abs(data.curvature), color="tab:blue", lw=2, label=r"curvature $|\omega/u|$"
    )
    ax_rate.semilogy(
        data.t, np.abs(data.z[:, 2]), color="tab:gray", lw=2, label=r"hitch angle $|\alpha_1|$"
    )
    t0, t1 = data.fit_window
    late = (data.t >= t0) & (data.t <= t1)
    for values, rate, color, name in (
        (data.curvature, data.lambda_0, "tab:blue", r"\lambda_0"),
        (data.z[:, 2], data.lambda_1, "tab:gray", r"\lambda_1"),
    ):
        anchor = float(np.abs(values[late][-1]))
        guide = anchor * np.exp(rate * (data.t - data.t[late][-1]))
        after = data.t >= 5.0
        ax_rate.semilogy(
            data.t[after],
            guide[after] * 5.0,
            "--",
            color=color,
            lw=1.2,
            label=f"slope ${name} = {rate:.4f}$ (theory, shifted up)",
        )
    ax_rate.axvspan(t0, t1, color="0.92", zorder=0)
    ax_rate.set_xlabel("t")
    ax_rate.set_title(
        f"slopes fitted in the grey window: curvature {data.curvature_rate:.6f} "
        f"(theory {data.lambda_0:.6f}), hitch angle {data.hitch_rate:.4f} "
        f"(theory {data.lambda_1:.4f})",
        fontsize=9,
    )
    ax_rate.legend(fontsize=8, loc="lower left")
    p = data.params
    fig.suptitle(
        rf"n = {n}, a = {p.a:g} > 0: the turn dies out at the stable node's rate "
        rf"$\lambda_0 = -(Ma/I_0)\sqrt{{2E/(M+nm)}}$"
        f"\nM={p.M:g}, J0={p.J0:g}, m={p.m:g}, J={p.J:g}, l={p.l:g}, E={data.E:g}",
        fontsize=10,
    )
    save_figure(fig, path)


# ----------------------------------------------------------------------------------------
# 3. f(alpha) = sin^2(alpha) / R(alpha) and the energy levels, n = 1, a = 0 (figure 3.3)
# ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class LevelFunction:
    """f on [0, pi] and the level l^2 omega0^2 / (2E - J0 omega0^2) of a few energies."""

    params: ConvoyParams
    omega0: float
    alpha: FloatArray
    f: FloatArray
    f_max: float  # l^2 / (J + M l^2), the thesis's maximum, at alpha = pi/2
    energies: FloatArray
    levels: FloatArray
    roots: list[tuple[float, float] | None]  # (alpha(1), alpha(2)) for E > E_c


def level_function(params: ConvoyParams, alpha: FloatArray) -> FloatArray:
    """f(alpha) = sin^2(alpha) / R(alpha) with R from ``dynamics.inertia_R``."""
    angles = np.asarray(alpha, dtype=float)
    return np.asarray(np.sin(angles) ** 2 / inertia_R(params, angles[..., None]))


def energy_level(params: ConvoyParams, E: float, omega0: float) -> float:
    """The level l^2 omega0^2 / (2E - J0 omega0^2) that f(alpha) meets at the equilibria."""
    return params.l**2 * omega0**2 / (2.0 * E - params.J0 * omega0**2)


def level_function_data(
    params: ConvoyParams = ONE_TRAILER_A0,
    omega0: float = OMEGA0,
    energy_ratios: Sequence[float] = (0.85, 1.0, 1.5),
    n_alpha: int = 401,
) -> LevelFunction:
    """f over [0, pi] and the levels of E = ratio * E_c, with the roots for E > E_c."""
    E_c = analysis.critical_energy(params, omega0)
    energies = np.array(energy_ratios) * E_c
    alpha = np.linspace(0.0, math.pi, n_alpha)
    roots: list[tuple[float, float] | None] = [
        analysis.one_trailer_equilibria(params, float(E), omega0) if E_c < E else None
        for E in energies
    ]
    return LevelFunction(
        params=params,
        omega0=omega0,
        alpha=alpha,
        f=level_function(params, alpha),
        f_max=params.l**2 / (params.J + params.M * params.l**2),
        energies=energies,
        levels=np.array([energy_level(params, float(E), omega0) for E in energies]),
        roots=roots,
    )


REGIME_COLORS = ("tab:blue", "tab:gray", "tab:red")  # E < E_c, E = E_c, E > E_c (figure 3.6)


def _regime_label(E: float, E_c: float) -> str:
    if math.isclose(E, E_c, rel_tol=1e-12):
        return r"$E = E_c$"
    return rf"$E = {E / E_c:.2f}\,E_c$"


def draw_level_function(data: LevelFunction, path: Path) -> None:
    """f(alpha) with the horizontal levels; where they meet f are the relative equilibria."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    ax.plot(data.alpha, data.f, color="black", lw=2, label=r"$f(\alpha)=\sin^2\alpha/R(\alpha)$")
    E_c = float(data.energies[np.argmin(np.abs(data.levels - data.f_max))])
    for E, level, roots, color in zip(
        data.energies, data.levels, data.roots, REGIME_COLORS, strict=True
    ):
        ax.axhline(level, color=color, ls="--", lw=1.3, label=_regime_label(float(E), E_c))
        if roots is not None:
            for root, name, face, offset in zip(
                roots,
                ("(1)", "(2)"),
                (color, "white"),
                ((-112, 6), (12, 6)),
                strict=True,
            ):
                ax.plot(root, level, "o", ms=9, mfc=face, mec=color, mew=2)
                kind = "stable" if face == color else "unstable"
                ax.annotate(
                    rf"$\alpha^{{{name}}}$ = {root:.4f} ({kind})",
                    (root, level),
                    textcoords="offset points",
                    xytext=offset,
                    fontsize=8,
                )
    ax.plot(math.pi / 2, data.f_max, "o", ms=7, color="tab:gray")
    ax.set_xticks(
        np.arange(0, 1.01, 0.25) * math.pi, ["0", r"$\pi/4$", r"$\pi/2$", r"$3\pi/4$", r"$\pi$"]
    )
    ax.set_xlim(0, math.pi)
    ax.set_ylim(0, 1.25 * float(max(data.levels.max(), data.f_max)))
    ax.set_xlabel(r"hitch angle $\alpha$")
    ax.set_ylabel(r"$f(\alpha)$ and $\ell^2\omega_0^2/(2E - J_0\omega_0^2)$")
    p = data.params
    ax.set_title(
        "n = 1, a = 0: the level of an energy E > E_c meets f twice (two relative equilibria);\n"
        f"that of E_c touches the top, max f = l²/(J + M l²) = {data.f_max:.4f}; "
        "below E_c no equilibrium\n"
        f"M={p.M:g}, J={p.J:g}, m={p.m:g}, l={p.l:g}, J0={p.J0:g}, ω0={data.omega0:g}",
        fontsize=9,
    )
    ax.legend(fontsize=8, loc="upper left")
    save_figure(fig, path)


# ----------------------------------------------------------------------------------------
# 4. Invariant circles and the cylinder omega = omega0 (figures 3.5 and 3.6)
# ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class CircleEquilibrium:
    """A relative equilibrium on an invariant circle: the cart runs on a circle."""

    alpha: float
    u: float
    stable: bool | None  # None: the semi-stable point of E = E_c


@dataclass(frozen=True)
class InvariantCircles:
    """The flow of (alpha, u) on the cylinder omega = omega0 and three invariant circles."""

    params: ConvoyParams
    omega0: float
    E_c: float
    alpha: FloatArray  # grid, [0, 2 pi]
    u: FloatArray  # grid
    alpha_dot: FloatArray  # (u, alpha)
    u_dot: FloatArray
    energies: FloatArray
    circle_u: FloatArray  # (energy, alpha): u on each invariant circle
    circle_rate: FloatArray  # alpha_dot along each circle
    equilibria: list[list[CircleEquilibrium]]
    equilibrium_curve: tuple[FloatArray, FloatArray]  # u = l omega0 / sin(alpha)


def invariant_circles_data(
    params: ConvoyParams = ONE_TRAILER_A0,
    omega0: float = OMEGA0,
    energy_ratios: Sequence[float] = (0.85, 1.0, 1.5),
    grid_size: int = 61,
    u_max: float = 2.2,
) -> InvariantCircles:
    """Sample the cylinder's flow through ``rhs`` and the three invariant circles of (3.37)."""
    E_c = analysis.critical_energy(params, omega0)
    energies = np.array(energy_ratios) * E_c
    alpha = np.linspace(0.0, 2.0 * math.pi, 4 * grid_size + 1)
    u_grid = np.linspace(0.02, u_max, grid_size)
    alpha_cells, u_cells = np.meshgrid(np.linspace(0.0, 2.0 * math.pi, grid_size), u_grid)
    z = np.stack([u_cells, np.full_like(u_cells, omega0), alpha_cells], axis=-1)
    field = rhs(params, z)
    budget = 2.0 * energies - params.J0 * omega0**2
    circle_u = np.sqrt(budget[:, None] / inertia_R(params, alpha[:, None])[None, :])
    circle_rate = np.stack(
        [analysis.one_trailer_hitch_rate(params, float(E), omega0, alpha) for E in energies]
    )
    equilibria: list[list[CircleEquilibrium]] = []
    for E in energies:
        on_circle: list[CircleEquilibrium] = []
        if math.isclose(E, E_c, rel_tol=1e-12):
            on_circle.append(CircleEquilibrium(math.pi / 2, params.l * omega0, None))
        elif E_c < E:
            for root, stable in zip(
                analysis.one_trailer_equilibria(params, float(E), omega0),
                (True, False),
                strict=True,
            ):
                on_circle.append(
                    CircleEquilibrium(root, params.l * omega0 / math.sin(root), stable)
                )
        equilibria.append(on_circle)
    curve_alpha = np.linspace(0.05, math.pi - 0.05, 200)
    curve_u = params.l * omega0 / np.sin(curve_alpha)
    keep = curve_u <= u_max
    return InvariantCircles(
        params=params,
        omega0=omega0,
        E_c=E_c,
        alpha=alpha_cells[0],
        u=u_grid,
        alpha_dot=field[..., 2],
        u_dot=field[..., 0],
        energies=energies,
        circle_u=circle_u,
        circle_rate=circle_rate,
        equilibria=equilibria,
        equilibrium_curve=(curve_alpha[keep], curve_u[keep]),
    )


def draw_invariant_circles(data: InvariantCircles, path: Path) -> None:
    """Top: the three invariant circles with their flow; bottom: the unrolled cylinder."""
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(10.5, 7.6))
    grid = fig.add_gridspec(2, 3, height_ratios=(1.0, 1.25))
    alpha_fine = np.linspace(0.0, 2.0 * math.pi, data.circle_u.shape[1])
    for column, (E, rate, on_circle, color) in enumerate(
        zip(data.energies, data.circle_rate, data.equilibria, REGIME_COLORS, strict=True)
    ):
        ax = fig.add_subplot(grid[0, column])
        ax.plot(np.cos(alpha_fine), np.sin(alpha_fine), color=color, lw=2)
        # Arrows along the circle in the direction alpha moves (alpha counter-clockwise).
        for angle in np.linspace(0.0, 2.0 * math.pi, 12, endpoint=False) + 0.13:
            index = int(np.argmin(np.abs(alpha_fine - angle)))
            sign = np.sign(rate[index])
            if sign == 0:
                continue
            tangent = sign * np.array([-math.sin(angle), math.cos(angle)])
            ax.annotate(
                "",
                xy=(math.cos(angle) + 0.18 * tangent[0], math.sin(angle) + 0.18 * tangent[1]),
                xytext=(math.cos(angle), math.sin(angle)),
                arrowprops={"arrowstyle": "-|>", "color": color, "lw": 1.2},
            )
        for point in on_circle:
            face = {True: color, False: "white", None: "0.6"}[point.stable]
            ax.plot(math.cos(point.alpha), math.sin(point.alpha), "o", ms=10, mfc=face, mec="black")
        ax.plot(0, 0, "+", color="0.5")
        ax.text(1.05, 0.0, r"$\alpha=0$", fontsize=8, va="center")
        ax.text(0.0, 1.08, r"$\pi/2$", fontsize=8, ha="center")
        ax.set_xlim(-1.35, 1.45)
        ax.set_ylim(-1.3, 1.35)
        ax.set_aspect("equal")
        ax.axis("off")
        description = {
            0: "no equilibrium:\n" r"$\alpha$ turns round periodically",
            1: r"one equilibrium ($\alpha=\pi/2$)" "\nand a homoclinic orbit",
            2: "stable (filled) and unstable\n(open) relative equilibria",
        }[int(np.sign(E - data.E_c)) + 1 if not math.isclose(E, data.E_c) else 1]
        ax.set_title(f"{_regime_label(float(E), data.E_c)}: {description}", fontsize=9)

    ax = fig.add_subplot(grid[1, :])
    ax.streamplot(
        data.alpha, data.u, data.alpha_dot, data.u_dot, color="0.75", density=1.1, linewidth=0.7
    )
    for E, u_curve, color in zip(data.energies, data.circle_u, REGIME_COLORS, strict=True):
        ax.plot(alpha_fine, u_curve, color=color, lw=2.2, label=_regime_label(float(E), data.E_c))
    curve_alpha, curve_u = data.equilibrium_curve
    ax.plot(
        curve_alpha, curve_u, color="black", lw=2, label=r"equilibria $u\sin\alpha=\ell\omega_0$"
    )
    for on_circle in data.equilibria:
        for point in on_circle:
            face = {True: "black", False: "white", None: "0.6"}[point.stable]
            ax.plot(point.alpha, point.u, "o", ms=8, mfc=face, mec="black", zorder=5)
    ax.set_xticks(
        np.arange(0, 2.01, 0.5) * math.pi, ["0", r"$\pi/2$", r"$\pi$", r"$3\pi/2$", r"$2\pi$"]
    )
    ax.set_xlim(0, 2 * math.pi)
    ax.set_ylim(0, data.u[-1])
    ax.set_xlabel(r"hitch angle $\alpha$ (the cylinder unrolled)")
    ax.set_ylabel("u")
    ax.legend(fontsize=8, loc="upper right", ncol=2)
    ax.set_title(
        rf"flow of $(\alpha, u)$ on the cylinder $\omega=\omega_0$; each energy level (3.37) "
        rf"is an invariant circle; "
        rf"$E_c = (J_0 + J + M\ell^2)\omega_0^2/2 = {data.E_c:g}$",
        fontsize=9,
    )
    fig.suptitle(
        rf"n = 1, a = 0, $\omega_0$ = {data.omega0:g}: the invariant circles change at the "
        "critical energy",
        fontsize=11,
    )
    save_figure(fig, path)


# ----------------------------------------------------------------------------------------
# 5. The cart's paths for E < E_c and E > E_c (thesis figure 3.7)
# ----------------------------------------------------------------------------------------


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


# ----------------------------------------------------------------------------------------
# 6. The singular set and the degree of nonholonomy (appendix A)
# ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SingularSlice:
    """The degree of nonholonomy on a grid of (alpha_1, alpha_2), the other angles fixed."""

    n: int
    fixed: tuple[float, ...]  # alpha_3..alpha_n
    grid: FloatArray
    degree: NDArray[np.int64]  # (alpha_2 index, alpha_1 index)
    margin: FloatArray  # singular_margin at the grid points


def angle_grid(points: int) -> FloatArray:
    """``points`` angles in [-pi, pi), spaced evenly; a multiple of 4 puts +-pi/2 on the grid."""
    return -math.pi + 2.0 * math.pi * np.arange(points) / points


def singular_slice_data(n: int, points: int, fixed: Sequence[float] = ()) -> SingularSlice:
    """Compute ``nonholonomy_degree`` at every grid point of (alpha_1, alpha_2).

    Args:
        n: Number of trailers, >= 2.
        points: Grid points per angle.
        fixed: alpha_3..alpha_n, held fixed.
    """
    if n < 2 or len(fixed) != n - 2:
        raise ValueError(f"need n >= 2 and n - 2 fixed angles, got n={n}, fixed={fixed}")
    grid = angle_grid(points)
    degree = np.empty((points, points), dtype=np.int64)
    configs = np.empty((points, points, n))
    for row, alpha_2 in enumerate(grid):
        for column, alpha_1 in enumerate(grid):
            config = np.array([alpha_1, alpha_2, *fixed])
            configs[row, column] = config
            degree[row, column] = nonholonomy_degree(n, config).degree
    return SingularSlice(
        n=n, fixed=tuple(fixed), grid=grid, degree=degree, margin=singular_margin(configs)
    )


def singular_set_data(quick: bool = False) -> list[SingularSlice]:
    """n = 2 on a fine grid, n = 3 on two alpha_3 slices (its value never matters)."""
    n2_points, n3_points = (8, 8) if quick else (48, 24)
    return [
        singular_slice_data(2, n2_points),
        singular_slice_data(3, n3_points, (0.0,)),
        singular_slice_data(3, n3_points, (math.pi / 2,)),
    ]


def pi_fraction(angle: float) -> str:
    """TeX for an angle as a simple fraction of pi: 0, \\pi/2, 3\\pi/4, ..."""
    fraction = Fraction(angle / math.pi).limit_denominator(12)
    if abs(float(fraction) * math.pi - angle) > 1e-9:
        return f"{angle:g}"
    if fraction == 0:
        return "0"
    numerator = {1: "", -1: "-"}.get(fraction.numerator, str(fraction.numerator))
    denominator = "" if fraction.denominator == 1 else f"/{fraction.denominator}"
    return rf"{numerator}\pi{denominator}"


EXCESS_COLORS = ("#eeeeee", "#6baed6", "#fd8d3c", "#a50f15", "#54278f")
"""Colour of degree - (n + 2): 0 (regular), 1, 2, 3, 4."""


def draw_singular_set(slices: list[SingularSlice], path: Path) -> None:
    """Degree of nonholonomy by colour, exact singular lines cos(alpha_k) = 0 dashed."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.patches import Patch

    cmap = ListedColormap(list(EXCESS_COLORS))
    norm = BoundaryNorm(np.arange(-0.5, len(EXCESS_COLORS)), cmap.N)
    fig, axes = plt.subplots(1, len(slices), figsize=(4.6 * len(slices), 5.6))
    for ax, piece in zip(axes, slices, strict=True):
        regular = piece.n + 2
        # The torus is periodic: repeat the first row and column at +pi to close the picture.
        step = piece.grid[1] - piece.grid[0]
        centres = np.append(piece.grid, math.pi)
        edges = np.append(centres, math.pi + step) - 0.5 * step
        closed = np.pad(piece.degree, ((0, 1), (0, 1)), mode="wrap")
        ax.pcolormesh(edges, edges, closed - regular, cmap=cmap, norm=norm)
        for line in (-0.5 * math.pi, 0.5 * math.pi):
            ax.axvline(line, color="black", ls="--", lw=0.8)  # cos(alpha_1) = 0
            if piece.n >= 3:
                ax.axhline(line, color="black", ls="--", lw=0.8)  # cos(alpha_2) = 0
        ticks = np.arange(-1.0, 1.01, 0.5) * math.pi
        names = [r"$-\pi$", r"$-\pi/2$", "0", r"$\pi/2$", r"$\pi$"]
        ax.set_xticks(ticks, names)
        ax.set_yticks(ticks, names)
        ax.set_xlim(-math.pi, math.pi)
        ax.set_ylim(-math.pi, math.pi)
        ax.set_xlabel(r"$\alpha_1$")
        ax.set_ylabel(r"$\alpha_2$")
        ax.set_aspect("equal")
        fixed = rf", $\alpha_3 = {pi_fraction(piece.fixed[0])}$" if piece.fixed else ""
        ax.set_title(
            f"n = {piece.n}{fixed}  (grid {piece.grid.size} x {piece.grid.size})", fontsize=10
        )
        handles = []
        for value in np.unique(piece.degree):
            count = int(np.sum(piece.degree == value))
            note = " (regular)" if value == regular else ""
            handles.append(
                Patch(
                    facecolor=EXCESS_COLORS[int(value) - regular],
                    edgecolor="0.4",
                    label=f"degree {value}{note}: {count} points",
                )
            )
        ax.legend(
            handles=handles,
            loc="upper center",
            bbox_to_anchor=(0.5, -0.14),
            ncol=2,
            fontsize=8,
            frameon=False,
        )
    fig.suptitle(
        "Degree of nonholonomy computed by Lie brackets at every grid point: n + 2 except on "
        r"the singular set $\cos\alpha_k = 0$, $k \leq n-1$ (dashed)"
        "\n"
        r"where it rises; for n = 3 the slices at $\alpha_3 = 0$ and $\pi/2$ agree "
        "(the last hitch angle never matters)",
        fontsize=10.5,
    )
    save_figure(fig, path)


# ----------------------------------------------------------------------------------------
# The command
# ----------------------------------------------------------------------------------------


def figure_jobs(quick: bool) -> list[tuple[str, Callable[[], object], Callable[..., None]]]:
    """(file name, data function, drawing function) of every picture."""
    dt = 0.02 if quick else 0.01
    return [
        (
            "thesis_torus_portrait.png",
            lambda: torus_portrait_data(grid_size=25 if quick else 41),
            draw_torus_portrait,
        ),
        ("thesis_straight_line.png", lambda: straight_line_data(dt=dt), draw_straight_line),
        ("thesis_level_function.png", level_function_data, draw_level_function),
        (
            "thesis_invariant_circles.png",
            lambda: invariant_circles_data(grid_size=31 if quick else 61),
            draw_invariant_circles,
        ),
        ("thesis_cart_paths.png", lambda: cart_paths_data(quick), draw_cart_paths),
        ("thesis_singular_set.png", lambda: singular_set_data(quick), draw_singular_set),
    ]


def main(argv: Sequence[str] | None = None) -> list[Path]:
    """Write every picture; return the paths written."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    default_out = Path(__file__).resolve().parent / "img"
    parser.add_argument("--out", type=Path, default=default_out, help="output folder")
    parser.add_argument("--quick", action="store_true", help="coarse grids, short runs")
    args = parser.parse_args(argv)

    import matplotlib

    matplotlib.use("Agg")
    args.out.mkdir(parents=True, exist_ok=True)
    written = []
    for name, compute, draw in figure_jobs(args.quick):
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            data = compute()
            target = args.out / name
            draw(data, target)
        size_kb = target.stat().st_size / 1024
        print(f"{target}  {size_kb:6.1f} kB  {time.perf_counter() - start:5.1f} s")
        written.append(target)
    return written


if __name__ == "__main__":
    main(sys.argv[1:])
