"""The degree of nonholonomy over the hitch-angle torus, n = 2, 3 (thesis appendix A)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from docs.figures._common import FloatArray, save_figure
from dynamics import singular_margin
from dynamics.nonholonomy import nonholonomy_degree


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
