"""The flow on the energy torus (alpha_1, beta), n = 1, a > 0 (thesis figure 3.2a)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from docs.figures._common import (
    ONE_TRAILER,
    TORUS_WINDOW,
    FloatArray,
    break_at_jumps,
    save_figure,
    wrap_into,
)
from dynamics import ConvoyParams, analysis, simulate

KIND_STYLE = {
    "stable node": {"color": "tab:green", "marker": "o"},
    "unstable node": {"color": "tab:red", "marker": "o"},
    "saddle": {"color": "tab:orange", "marker": "X"},
}


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
