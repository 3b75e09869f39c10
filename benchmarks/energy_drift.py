"""Energy drift over 10^5 control steps with mu = 0: energy-preserving RK4 against plain RK4.

Run with ``python -m benchmarks.energy_drift [--quick]``.

A passive convoy (mu = 0) coasts for 10^5 control steps of dt = 0.05 s (5000 s)
with one RK4 substep per step, from the forward and the reversing scenes of
:mod:`benchmarks._common` (n = 3; both settle on an equilibrium) and from a
scene that never settles (see :func:`scenarios`), stepped as an environment steps it: one
:meth:`dynamics.Stepper.step` call per control step. Recorded every step:
``|E - E0| / E0``. The energy-preserving step is run twice: holding the energy at
the start of each call (the default) and holding E0 across calls
(``target_energy``), which keeps rounding errors from accumulating call after call.

A run writes under ``--results``/``--images`` (default ``out/benchmarks/``); the
committed outputs: ``benchmarks/results/energy_drift.csv`` and ``docs/img/bench_energy_drift.png``.
"""

from __future__ import annotations

import inspect
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks._common import (
    SCENES,
    one_thread,
    parse_command,
    pyplot,
    report_written,
    save_figure,
    scene_state,
    write_csv,
)
from dynamics import ConvoyParams, Stepper, energy

DT = 0.05
STEPS = 100_000
EPSILON = np.finfo(float).eps


def drift(params: ConvoyParams, z0: np.ndarray, variant: str, steps: int) -> np.ndarray:
    """|E - E0| / E0 after each of ``steps`` control steps."""
    stepper = Stepper(params, preserve_energy=variant != "RK4")
    z = z0[None, :].copy()
    act = np.array([[params.b, 0.0, 0.0, 0.0, 0.0, 0.0]])
    one = np.ones(1, dtype=np.int64)
    e0 = float(energy(params, z0))
    held = np.full(1, e0)
    states = np.empty((steps, z0.size))
    for k in range(steps):
        if variant == "RK4 energy-preserving, E0 held":
            stepper.step(z, act, DT, one, target_energy=held)
        else:
            stepper.step(z, act, DT, one)
        states[k] = z[0]
    return np.abs(energy(params, states) - e0) / e0


def scenarios() -> dict[str, tuple[ConvoyParams, np.ndarray]]:
    """The two benchmark scenes with n = 3, and one that never settles.

    With a = 0 and one trailer below the critical energy (physics.md section 8:
    omega = 1, u = 0.5, E = 0.35 < E_c = 0.65) the trailer turns round and round
    forever, so the run never comes to rest at an equilibrium.
    """
    out = {
        f"{scene}, n = 3": (ConvoyParams(n_trailers=3, mu=0.0), scene_state(scene, 3))
        for scene in SCENES
    }
    out["a = 0, n = 1: trailer turning forever"] = (
        ConvoyParams(n_trailers=1, a=0.0, mu=0.0),
        np.array([0.5, 1.0, 0.0]),
    )
    return out


def variants() -> tuple[str, ...]:
    """The variants this version of :class:`dynamics.Stepper` supports."""
    names: tuple[str, ...] = ("RK4", "RK4 energy-preserving")
    if "target_energy" in inspect.signature(Stepper.step).parameters:
        names += ("RK4 energy-preserving, E0 held",)
    return names


def measure(steps: int) -> tuple[dict[tuple[str, str], np.ndarray], list[dict[str, Any]]]:
    """Drift curves per (scene, variant) over ``steps`` control steps, and a CSV row each."""
    rows: list[dict[str, Any]] = []
    curves = {}
    for scene, (params, z0) in scenarios().items():
        for variant in variants():
            errors = drift(params, z0, variant, steps)
            curves[scene, variant] = errors
            rows.append(
                dict(
                    scene=scene,
                    variant=variant,
                    steps=steps,
                    max_relative_drift=float(errors.max()),
                    final_relative_drift=float(errors[-1]),
                    max_drift_in_eps=float(errors.max() / EPSILON),
                )
            )
            print(
                f"{scene:38s} {variant:32s}: max |E - E0| / E0 over {steps} steps = "
                f"{errors.max():.2e} ({errors.max() / EPSILON:.1f} eps), final {errors[-1]:.2e}"
            )
    return curves, rows


def plot(curves: dict[tuple[str, str], np.ndarray], steps: int, path: Path) -> Path:
    """One log-log panel of the drift curves per scene."""
    scenes = list(dict.fromkeys(scene for scene, _ in curves))
    plt = pyplot()
    fig, axes = plt.subplots(1, len(scenes), figsize=(15, 4), sharey=True)
    index = np.arange(1, steps + 1)
    thinned = np.unique(np.geomspace(1, steps, 400).astype(int)) - 1
    for ax, scene in zip(axes, scenes, strict=True):
        for variant in variants():
            ax.loglog(
                index[thinned],
                np.maximum(curves[scene, variant][thinned], 1e-18),
                lw=1,
                label=variant,
            )
        ax.axhline(EPSILON, color="k", ls=":", lw=1, label="machine epsilon")
        ax.set_xlabel(f"control step (dt = {DT} s, 1 substep)")
        ax.set_title(f"{scene}, mu = 0", fontsize=10)
        ax.grid(True, which="major", alpha=0.3)
    axes[0].set_ylabel("|E - E0| / E0")
    axes[-1].legend(fontsize=7)
    fig.suptitle("Energy drift over control steps (values below 1e-18 drawn at 1e-18)", fontsize=10)
    return save_figure(fig, path)


def main(argv: list[str] | None = None) -> int:
    args = parse_command(
        "python -m benchmarks.energy_drift", __doc__, "10^4 steps instead of 10^5", argv
    )
    start = time.perf_counter()
    steps = STEPS // 10 if args.quick else STEPS
    with one_thread():
        curves, rows = measure(steps)
    write_csv(args.results / "energy_drift.csv", rows)
    path = plot(curves, steps, args.images / "bench_energy_drift.png")
    report_written(f"{args.results / 'energy_drift.csv'} and {path}", start)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
