"""Invariant circles and the cylinder omega = omega0, n = 1, a = 0 (figures 3.5, 3.6)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from docs.figures._common import (
    OMEGA0,
    ONE_TRAILER_A0,
    REGIME_COLORS,
    FloatArray,
    regime_label,
    save_figure,
)
from dynamics import ConvoyParams, analysis, inertia_R, rhs


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
        ax.set_title(f"{regime_label(float(E), data.E_c)}: {description}", fontsize=9)

    ax = fig.add_subplot(grid[1, :])
    ax.streamplot(
        data.alpha, data.u, data.alpha_dot, data.u_dot, color="0.75", density=1.1, linewidth=0.7
    )
    for E, u_curve, color in zip(data.energies, data.circle_u, REGIME_COLORS, strict=True):
        ax.plot(alpha_fine, u_curve, color=color, lw=2.2, label=regime_label(float(E), data.E_c))
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
