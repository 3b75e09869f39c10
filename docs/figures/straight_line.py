"""The cart's path straightening out, a > 0 (thesis figure 3.2b)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from docs.figures._common import ONE_TRAILER, FloatArray, draw_convoy, fit_decay_rate, save_figure
from dynamics import ConvoyParams, analysis, body_poses, simulate


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
