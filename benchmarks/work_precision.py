"""Work-precision chart: error against CPU time per simulated second.

Run with ``python -m benchmarks.work_precision [--quick]``.

For n = 1, 3, 8 and two scenes (forward: stable node; reversing: unstable node,
see :mod:`benchmarks._common`) every method integrates ``T`` simulated seconds.
Two errors are charted against CPU seconds per simulated second:

* final-state error: max-norm distance to a reference solved by scipy DOP853 at
  rtol = atol = 1e-13 (cross-checked against our DOPRI5 at 1e-13; the distance
  between the two is printed and stored as ``reference_gap``);
* energy error: max over the run of ``|E(t) - E(0)| / E(0)`` (the energy is
  conserved in these scenes).

Methods: fixed-step RK4 (:class:`dynamics.Stepper`) over a sweep of step sizes,
the same with the energy-preserving rescaling, our DOPRI5
(:func:`dynamics.adaptive.integrate_adaptive`) over a sweep of tolerances, and
scipy ``solve_ivp`` RK45, DOP853, LSODA and Radau over a sweep of tolerances.
scipy gets the same jitted field without the validation layer
(:func:`benchmarks._common.field_for_scipy`) and finite-difference Jacobians.

Timing: each timed run integrates the whole interval in one call (ours: one
:class:`dynamics.Stepper` / :class:`dynamics.adaptive.AdaptiveStepper` call, as a
hot loop would make; scipy: one ``solve_ivp`` without ``t_eval``). Each case is
timed in three interleaved passes and keeps its best (see
:func:`benchmarks._common.best_of_rounds`). The
energy is read from a second, untimed run sampled every ``SAMPLE`` seconds (for
RK4 with the same steps; for DOPRI5 with steps shortened to land on the
samples); scipy's energy is read at its own steps in the timed run.

A run writes under ``--results``/``--images`` (default ``out/benchmarks/``); the
committed outputs: ``benchmarks/results/work_precision.csv``,
``benchmarks/results/work_precision_speedup.csv`` (CPU time of the best scipy
method at equal final-state error, divided by ours, per RK4 and DOPRI5 point),
``docs/img/bench_work_precision_state.png`` and ``bench_work_precision_energy.png``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from benchmarks._common import (
    SCENES,
    best_of_rounds,
    field_for_scipy,
    machine_note,
    one_thread,
    parse_command,
    pyplot,
    report_written,
    save_figure,
    scene_params,
    scene_state,
    write_csv,
)
from dynamics import ConvoyParams, Stepper, energy
from dynamics.adaptive import AdaptiveStepper, integrate_adaptive

T = 20.0
SAMPLE = 0.5
STEPS_PER_SECOND = (5, 10, 20, 40, 80, 160, 320, 640, 1280)
ADAPTIVE_TOLERANCES = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)
SCIPY_TOLERANCES = {
    "RK45": (1e-3, 1e-5, 1e-7, 1e-9, 1e-11),
    "DOP853": (1e-3, 1e-5, 1e-7, 1e-9, 1e-11, 1e-12),
    "LSODA": (1e-3, 1e-5, 1e-7, 1e-9, 1e-11),
    "Radau": (1e-3, 1e-5, 1e-7, 1e-9),
}
REFERENCE_TOLERANCE = 1e-13
STYLE = {
    "RK4": dict(color="C0", marker="o"),
    "RK4 energy-preserving": dict(color="C1", marker="s"),
    "DOPRI5 (ours)": dict(color="C2", marker="^"),
    "scipy RK45": dict(color="C3", marker="v", ls="--"),
    "scipy DOP853": dict(color="C4", marker="D", ls="--"),
    "scipy LSODA": dict(color="C5", marker="x", ls="--"),
    "scipy Radau": dict(color="C6", marker="+", ls="--"),
}


def _energy_error(params: ConvoyParams, states: np.ndarray, reference_energy: float) -> float:
    values = energy(params, states)
    return float(np.max(np.abs(values - reference_energy)) / reference_energy)


def _state_error(z: np.ndarray, reference: np.ndarray) -> float:
    return float(np.max(np.abs(z - reference))) if np.all(np.isfinite(z)) else float("inf")


def reference_solution(params: ConvoyParams, z0: np.ndarray) -> tuple[np.ndarray, float]:
    """scipy DOP853 at 1e-13, and its max-norm distance to our DOPRI5 at 1e-13."""
    scipy_ref = solve_ivp(
        field_for_scipy(params),
        (0.0, T),
        z0,
        method="DOP853",
        rtol=REFERENCE_TOLERANCE,
        atol=REFERENCE_TOLERANCE,
    ).y[:, -1]
    ours = integrate_adaptive(params, z0, T, rtol=REFERENCE_TOLERANCE, atol=REFERENCE_TOLERANCE).z
    return scipy_ref, float(np.max(np.abs(scipy_ref - ours)))


def _rk4_runs(
    params: ConvoyParams, z0: np.ndarray, steps_per_second: int, preserve: bool
) -> tuple[Callable[[], Any], np.ndarray, float]:
    stepper = Stepper(params, preserve_energy=preserve)
    act = np.array([[params.b, 0.0, 0.0, 0.0, 0.0, 0.0]])
    total_steps = np.array([round(steps_per_second * T)], dtype=np.int64)

    def timed() -> np.ndarray:
        rows = z0[None, :].copy()
        stepper.step(rows, act.copy(), T, total_steps)
        return rows[0]

    per_sample = np.array([round(steps_per_second * SAMPLE)], dtype=np.int64)
    rows = z0[None, :].copy()
    samples = [rows[0].copy()]
    for _ in range(round(T / SAMPLE)):
        stepper.step(rows, act.copy(), SAMPLE, per_sample)
        samples.append(rows[0].copy())
    return timed, np.array(samples), T / total_steps[0]


def scene_cases(
    n: int, scene: str, quick: bool
) -> tuple[list[dict[str, Any]], list[Callable[[], Any]], float]:
    """All methods on one scene: CSV rows (no times yet), their timed runs, the reference gap."""
    params = scene_params(n)
    z0 = scene_state(scene, n)
    e0 = float(energy(params, z0))
    reference, gap = reference_solution(params, z0)
    rows: list[dict[str, Any]] = []
    runs: list[Callable[[], Any]] = []

    def record(
        method: str,
        setting: float,
        run: Callable[[], Any],
        final: np.ndarray,
        energy_error: float,
        evaluations: float,
    ) -> None:
        rows.append(
            dict(
                n=n,
                scene=scene,
                method=method,
                setting=setting,
                cpu_per_sim_second=float("nan"),
                state_error=_state_error(final, reference),
                energy_error=energy_error,
                evaluations=evaluations,
                reference_gap=gap,
            )
        )
        runs.append(run)

    thin = (lambda values: values[::3]) if quick else (lambda values: values)
    for preserve, method in ((False, "RK4"), (True, "RK4 energy-preserving")):
        for steps_per_second in thin(STEPS_PER_SECOND):
            timed, samples, h = _rk4_runs(params, z0, steps_per_second, preserve)
            record(
                method,
                h,
                timed,
                timed(),
                _energy_error(params, samples, e0),
                4 * steps_per_second * T,
            )

    sample_times = np.arange(0.0, T + 0.5 * SAMPLE, SAMPLE)
    act = np.array([[params.b, 0.0, 0.0, 0.0, 0.0, 0.0]])
    for tolerance in thin(ADAPTIVE_TOLERANCES):
        # Timed like RK4: the in-place stepper a hot loop would use, one kernel call.
        stepper = AdaptiveStepper(params, rtol=tolerance, atol=tolerance)

        def adaptive(stepper: AdaptiveStepper = stepper) -> np.ndarray:
            rows = z0[None, :].copy()
            stepper.step(rows, act.copy(), T, np.zeros(1))
            return rows[0]

        result = integrate_adaptive(params, z0, T, rtol=tolerance, atol=tolerance)
        assert np.array_equal(result.z, adaptive())
        sampled = integrate_adaptive(
            params, z0, T, rtol=tolerance, atol=tolerance, t_eval=sample_times
        )
        assert sampled.z_samples is not None
        record(
            "DOPRI5 (ours)",
            tolerance,
            adaptive,
            result.z,
            _energy_error(params, sampled.z_samples, e0),
            float(result.evaluations),
        )

    field = field_for_scipy(params)
    for name, tolerances in SCIPY_TOLERANCES.items():
        for tolerance in thin(tolerances):

            def scipy_run(tol: float = tolerance, method: str = name) -> Any:
                return solve_ivp(field, (0.0, T), z0, method=method, rtol=tol, atol=tol)

            solution = scipy_run()
            final = solution.y[:, -1] if solution.success else np.full(n + 2, np.inf)
            record(
                f"scipy {name}",
                tolerance,
                scipy_run,
                final,
                _energy_error(params, solution.y.T, e0),
                float(solution.nfev),
            )
    return rows, runs, gap


def speedups(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Best scipy CPU time at our final-state error, over ours, for each RK4 / DOPRI5 point.

    The best scipy time at error e is the smallest, over the four scipy methods, of
    the log-log interpolation of that method's (error, time) points; points whose
    error lies outside every scipy method's measured range get no ratio.
    """
    out = []
    for n, scene in sorted({(row["n"], row["scene"]) for row in rows}):
        subset = [row for row in rows if row["n"] == n and row["scene"] == scene]
        curves = []
        for name in SCIPY_TOLERANCES:
            points = sorted(
                (row["state_error"], row["cpu_per_sim_second"])
                for row in subset
                if row["method"] == f"scipy {name}" and np.isfinite(row["state_error"])
            )
            if len(points) >= 2:
                errors, times = np.log10(np.array(points)).T
                curves.append((name, errors, times))
        for row in subset:
            if row["method"] not in ("RK4", "DOPRI5 (ours)") or not row["state_error"] > 0:
                continue
            error = np.log10(row["state_error"])
            best_name, best_time = "", np.inf
            for name, errors, times in curves:
                if errors[0] <= error <= errors[-1]:
                    time_at_error = 10 ** np.interp(error, errors, times)
                    if time_at_error < best_time:
                        best_name, best_time = name, time_at_error
            out.append(
                dict(
                    n=n,
                    scene=scene,
                    method=row["method"],
                    setting=row["setting"],
                    state_error=row["state_error"],
                    cpu_per_sim_second=row["cpu_per_sim_second"],
                    best_scipy=best_name or "out of range",
                    scipy_cpu_per_sim_second=best_time if best_name else float("nan"),
                    speedup=best_time / row["cpu_per_sim_second"] if best_name else float("nan"),
                )
            )
    return out


def plot(rows: list[dict[str, Any]], column: str, ylabel: str, title: str, path: Path) -> Path:
    """One panel per (scene, n): ``column`` against CPU seconds per simulated second."""
    plt = pyplot()
    ns = sorted({row["n"] for row in rows})
    scenes = [scene for scene in SCENES if any(row["scene"] == scene for row in rows)]
    fig, axes = plt.subplots(
        len(scenes),
        len(ns),
        figsize=(4.2 * len(ns), 3.6 * len(scenes)),
        squeeze=False,
        sharex=True,
        sharey=True,
    )
    floor = 1e-17
    for i, scene in enumerate(scenes):
        for j, n in enumerate(ns):
            ax = axes[i, j]
            for method, style in STYLE.items():
                points = sorted(
                    (row["cpu_per_sim_second"], max(row[column], floor))
                    for row in rows
                    if row["n"] == n
                    and row["scene"] == scene
                    and row["method"] == method
                    and np.isfinite(row[column])
                )
                if points:
                    x, y = np.array(points).T
                    ax.loglog(x, y, label=method, ms=4, lw=1, **style)
            gaps = [row["reference_gap"] for row in rows if row["n"] == n and row["scene"] == scene]
            if column == "state_error" and gaps:
                # Below this the reference itself is not trusted: DOP853 and DOPRI5 at 1e-13 differ.
                ax.axhline(max(gaps[0], floor), color="k", ls=":", lw=0.8, label="reference gap")
            ax.set_title(f"{scene}, n = {n}", fontsize=10)
            ax.grid(True, which="major", alpha=0.3)
            if i == len(scenes) - 1:
                ax.set_xlabel("CPU s per simulated s")
            if j == 0:
                ax.set_ylabel(ylabel)
    axes[0, -1].legend(fontsize=7, loc="upper right")
    fig.suptitle(f"{title} (T = {T:g} s, |u0| = 1; {machine_note()}, one thread)", fontsize=10)
    return save_figure(fig, path)


def measure(quick: bool) -> list[dict[str, Any]]:
    """Errors and timings of every method and setting, per (n, scene): rows for the CSV."""
    cases = [(3, "forward")] if quick else [(n, scene) for scene in SCENES for n in (1, 3, 8)]
    rows: list[dict[str, Any]] = []
    runs: list[Callable[[], Any]] = []
    for n, scene in cases:
        scene_rows, scene_runs, gap = scene_cases(n, scene, quick)
        rows.extend(scene_rows)
        runs.extend(scene_runs)
        print(
            f"n = {n}, {scene}: reference gap (scipy DOP853 vs DOPRI5, both at 1e-13) = {gap:.1e}"
        )
    for row, seconds in zip(rows, best_of_rounds(runs, rounds=2 if quick else 3), strict=True):
        row["cpu_per_sim_second"] = seconds / T
    return rows


def main(argv: list[str] | None = None) -> int:
    args = parse_command(
        "python -m benchmarks.work_precision",
        __doc__,
        "n = 3, forward scene, a third of the points",
        argv,
    )
    start = time.perf_counter()
    with one_thread():
        rows = measure(args.quick)
    write_csv(args.results / "work_precision.csv", rows)
    ratios = speedups(rows)
    write_csv(args.results / "work_precision_speedup.csv", ratios)
    for row in ratios:
        print(
            f"  n = {row['n']}, {row['scene']:9s} {row['method']:14s} "
            f"setting {row['setting']:.1e}: "
            f"error {row['state_error']:.1e}, {row['cpu_per_sim_second'] * 1e3:8.3f} ms/sim-s; "
            f"best scipy {row['best_scipy']:>12s}: speedup {row['speedup']:7.1f}"
        )
    plot(
        rows,
        "state_error",
        "final-state error (max norm)",
        "Work-precision: final state",
        args.images / "bench_work_precision_state.png",
    )
    plot(
        rows,
        "energy_error",
        "max |E - E0| / E0",
        "Work-precision: energy",
        args.images / "bench_work_precision_energy.png",
    )
    report_written(
        f"{args.results}/work_precision*.csv and {args.images}/bench_work_precision_*.png", start
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
