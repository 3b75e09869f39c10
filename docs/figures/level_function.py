"""f(alpha) = sin^2(alpha) / R(alpha) and the energy levels, n = 1, a = 0 (thesis figure 3.3)."""

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
from dynamics import ConvoyParams, analysis, inertia_R


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


def draw_level_function(data: LevelFunction, path: Path) -> None:
    """f(alpha) with the horizontal levels; where they meet f are the relative equilibria."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    ax.plot(data.alpha, data.f, color="black", lw=2, label=r"$f(\alpha)=\sin^2\alpha/R(\alpha)$")
    E_c = float(data.energies[np.argmin(np.abs(data.levels - data.f_max))])
    for E, level, roots, color in zip(
        data.energies, data.levels, data.roots, REGIME_COLORS, strict=True
    ):
        ax.axhline(level, color=color, ls="--", lw=1.3, label=regime_label(float(E), E_c))
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
