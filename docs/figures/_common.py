"""Helpers the thesis pictures share: convoys, wrapping, crossing times, fits, saving."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicHermiteSpline

from dynamics import ConvoyParams, body_poses

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

REGIME_COLORS = ("tab:blue", "tab:gray", "tab:red")  # E < E_c, E = E_c, E > E_c (figure 3.6)


def regime_label(E: float, E_c: float) -> str:
    """Legend text of an energy level: ``E = E_c`` or its ratio to E_c."""
    if math.isclose(E, E_c, rel_tol=1e-12):
        return r"$E = E_c$"
    return rf"$E = {E / E_c:.2f}\,E_c$"


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
