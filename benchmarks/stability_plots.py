"""The charts of ``python -m benchmarks.stability``: stability limits and failure modes.

Drawn from the rows that :mod:`benchmarks.stability` measures (its CSVs' columns);
the stability functions and limits drawn with them are that module's too.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from benchmarks._common import machine_note, pyplot, save_figure
from benchmarks.stability_theory import (
    DOPRI5_FIXED,
    METHODS,
    RK4,
    RK4_ENERGY_PRESERVING,
    real_axis_limit,
    stability_function,
)

OUTCOME_COLORS = {
    "true equilibrium": "tab:green",
    "true equilibrium, energy lost": "tab:olive",
    "spurious fixed point": "tab:orange",
    "spurious period-2 orbit": "tab:purple",
    "wandering": "tab:gray",
    "blow-up": "tab:red",
}


def plot_limits(limits: list[dict[str, Any]], path: Path) -> Path:
    """|R(-x)| with the limits, and measured against theoretical limits."""
    plt = pyplot()
    fig, (ax_r, ax_m) = plt.subplots(1, 2, figsize=(11, 4.2))
    x = np.linspace(0.0, 4.0, 400)
    for method, color in ((RK4, "C0"), (DOPRI5_FIXED, "C2")):
        function = stability_function(method)
        ax_r.plot(x, [abs(function(-v)) for v in x], color=color, label=f"|R(-x)|, {method}")
        limit = real_axis_limit(method)
        ax_r.axvline(limit, color=color, ls=":", lw=1)
        ax_r.annotate(
            f"x* = {limit:.4f}",
            (limit, 1.6),
            color=color,
            fontsize=8,
            rotation=90,
            ha="right",
            va="top",
        )
    ax_r.axhline(1.0, color="k", lw=0.8)
    ax_r.set_ylim(0, 2)
    ax_r.set_xlabel("x = h |lambda| (lambda real, negative)")
    ax_r.set_ylabel("|R(-x)|, growth per step")
    ax_r.set_title("Stability functions on the negative real axis")
    ax_r.legend(fontsize=8, loc="upper left")
    markers = {RK4: "o", RK4_ENERGY_PRESERVING: "s", DOPRI5_FIXED: "^"}
    colors = {RK4: "C0", RK4_ENERGY_PRESERVING: "C1", DOPRI5_FIXED: "C2"}
    labels = list(dict.fromkeys(row["case"] for row in limits))
    speeds = sorted({row["speed"] for row in limits})
    for method in METHODS:
        for speed_index, speed in enumerate(speeds):
            rows = [row for row in limits if row["method"] == method and row["speed"] == speed]
            offset = 0.25 * (METHODS.index(method) - 1) + 0.06 * (speed_index - 0.5)
            ax_m.scatter(
                [labels.index(row["case"]) + offset for row in rows],
                [100 * row["relative_gap"] for row in rows],
                marker=markers[method],
                color=colors[method],
                s=28,
                alpha=1.0 if speed_index else 0.5,
                label=f"{method}, |u| = {speed:g}",
            )
            ax_m.scatter(
                [labels.index(row["case"]) + offset for row in rows],
                [100 * (row["linear_model_x"] / row["theory_x"] - 1) for row in rows],
                marker="_",
                color="k",
                s=60,
                label="linearised model, same test"
                if method == METHODS[0] and not speed_index
                else None,
            )
    ax_m.axhline(0.0, color="k", lw=0.8)
    ax_m.set_xticks(
        range(len(labels)), [label.replace(" (", "\n(") for label in labels], fontsize=7
    )
    ax_m.set_ylabel("measured / theory - 1  [%]")
    ax_m.set_title("Largest stable h max|lambda| against x* (2.7853 / 3.3066)")
    ax_m.legend(fontsize=7)
    fig.suptitle("Stability of the fixed-step integrators at the forward equilibrium", fontsize=10)
    return save_figure(fig, path)


def plot_failures(
    failures: list[dict[str, Any]],
    adaptive: dict[float, np.ndarray],
    horizons: list[dict[str, Any]],
    path: Path,
) -> Path:
    """Outcome map, energy after the run, adaptive step sizes, predictability horizon."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(12, 8))
    ax_map, ax_energy, ax_adaptive, ax_horizon = axes.ravel()
    for row_index, method in enumerate(METHODS):
        rows = [row for row in failures if row["method"] == method]
        xs = np.array([row["x"] for row in rows])
        width = np.min(np.diff(xs)) if xs.size > 1 else 0.1
        for row in rows:
            ax_map.barh(
                row_index,
                width,
                left=row["x"] - width / 2,
                color=OUTCOME_COLORS[row["outcome"]],
                height=0.7,
            )
    for outcome, color in OUTCOME_COLORS.items():
        ax_map.barh(0, 0, color=color, label=outcome)
    for method, color in ((RK4, "k"), (DOPRI5_FIXED, "k")):
        ax_map.axvline(real_axis_limit(method), color=color, ls=":", lw=1)
    ax_map.set_yticks(range(len(METHODS)), METHODS, fontsize=8)
    ax_map.set_xlim(1.9, 10.1)
    ax_map.set_xlabel("dimensionless step x = h |u| / l")
    ax_map.set_title("Where a perturbed forward node ends (4000 steps); dotted: x*")
    ax_map.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=3)

    for method, style in ((RK4, "o-"), (DOPRI5_FIXED, "^-")):
        rows = [row for row in failures if row["method"] == method]
        finite = [
            (row["x"], row["energy_ratio"]) for row in rows if np.isfinite(row["energy_ratio"])
        ]
        xs, ratios = np.array(finite).T
        ax_energy.semilogy(xs, ratios, style, ms=2, lw=1, label=f"{method}: E_end / E0")
        ax_energy.semilogy(
            xs,
            [
                (real_axis_limit(method) / v) ** 2 if v > real_axis_limit(method) else 1.0
                for v in xs
            ],
            ":",
            lw=1,
            label=f"{method}: (x*/x)^2, back under x*",
        )
        blown = [row["x"] for row in rows if row["outcome"] == "blow-up"]
        if blown:
            ax_energy.axvline(
                min(blown),
                ls="--",
                lw=1,
                color="tab:red" if method == RK4 else "tab:pink",
                label=f"{method}: first blow-up, x = {min(blown):.2f}",
            )
    ax_energy.set_xlabel("dimensionless step x = h |u| / l")
    ax_energy.set_ylabel("energy after 4000 steps / initial energy")
    ax_energy.set_title("Energy drift: unstable steps bleed energy until h |u| / l < x*")
    ax_energy.legend(fontsize=7)

    dopri_limit = real_axis_limit(DOPRI5_FIXED)
    for tolerance, values in adaptive.items():
        ax_adaptive.plot(
            values, lw=0.8, label=f"rtol = atol = {tolerance:g}: mean {np.mean(values):.3f}"
        )
    ax_adaptive.axhline(
        dopri_limit, color="k", ls=":", lw=1, label=f"DOPRI5 x* = {dopri_limit:.3f}"
    )
    ax_adaptive.set_xlabel("accepted step")
    ax_adaptive.set_ylabel("h |u| / l")
    ax_adaptive.set_title("Error-controlled DOPRI5 at the node: steps ride the stability boundary")
    ax_adaptive.legend(fontsize=7)

    for (n, method, x), marker in (
        ((1, "exact", 0.0), "o"),
        ((3, "exact", 0.0), "s"),
        ((1, RK4, 2.0), "^"),
        ((3, RK4, 2.0), "v"),
    ):
        rows = [
            row for row in horizons if row["n"] == n and row["method"] == method and row["x"] == x
        ]
        for epsilon_index, epsilon in enumerate(sorted({row["epsilon"] for row in rows})):
            subset = sorted(
                (row["rate"], row["measured"], row["predicted"])
                for row in rows
                if row["epsilon"] == epsilon
            )
            rates, measured, predicted = np.array(subset).T
            color = f"C{epsilon_index}"
            label = f"n = {n}, {method}{'' if method == 'exact' else f' x = {x:g}'}"
            ax_horizon.loglog(
                rates,
                measured,
                marker,
                color=color,
                ms=4,
                mfc="none",
                label=f"{label}, eps = {epsilon:g}",
            )
            ax_horizon.loglog(
                rates, predicted, "-" if method == "exact" else "--", color=color, lw=0.7
            )
    ticks = sorted({row["rate"] for row in horizons})
    ax_horizon.set_xticks(ticks, [f"{tick:g}" for tick in ticks])
    ax_horizon.xaxis.set_minor_formatter(plt.NullFormatter())
    ax_horizon.set_xlabel("eigenvalue lambda = |u| / l of the reversing node")
    ax_horizon.set_ylabel("time for a deviation eps to reach 0.01")
    ax_horizon.set_title("Predictability horizon ~ ln(0.01 / eps) / lambda (lines: theory)")
    ax_horizon.legend(fontsize=6, ncol=2)
    fig.suptitle(f"How the integrators fail ({machine_note()})", fontsize=10)
    return save_figure(fig, path, dpi=80)
