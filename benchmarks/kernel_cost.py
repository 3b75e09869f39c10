"""Cost of the RK4 kernel per substep against the number of trailers and the batch size.

Run with ``python -m benchmarks.kernel_cost [--quick]``.

Each case calls :meth:`dynamics.Stepper.step` on a batch of ``B`` states of a
convoy with ``n`` trailers (default parameters, the mass moving on its rail),
with ``K`` substeps per call, ``K = clip(4096 // B, 1, 64)``, so that the
fixed cost of one call is spread over enough work to show the kernel itself.
The single-state case is also measured at ``K = 1`` (one substep per call, as
an environment with the lowest fidelity makes them): there the per-call
overhead dominates. Reported per case, on wall-clock time (the best of three
interleaved passes): state-substeps per second (``B K`` substeps per call) and
nanoseconds per substep per state, on one numba thread and on all of them.

A run writes under ``--results``/``--images`` (default ``out/benchmarks/``); the
committed outputs: ``benchmarks/results/kernel_cost.csv``, ``docs/img/bench_kernel_cost.png``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks._common import (
    best_of_rounds,
    machine_note,
    parse_command,
    pyplot,
    report_written,
    save_figure,
    set_threads,
    write_csv,
)
from dynamics import ConvoyParams, Stepper

NS = (1, 2, 3, 4, 6, 8, 12, 16, 24, 32)
BATCHES = (1, 4, 16, 64, 256, 1024, 4096, 16384)
DT = 0.05


def substeps_per_call(batch: int) -> int:
    """Enough substeps per call that the call overhead does not hide the kernel."""
    return int(np.clip(4096 // batch, 1, 64))


def make_case(n: int, batch: int, substeps: int, seed: int = 0) -> Callable[[], Any]:
    """A closure advancing ``batch`` random states of an n-trailer convoy by one call."""
    params = ConvoyParams(n_trailers=n)
    rng = np.random.default_rng(seed)
    z0 = np.zeros((batch, n + 2))
    z0[:, 0] = rng.uniform(0.5, 1.5, batch) * rng.choice([-1.0, 1.0], batch)
    z0[:, 1] = rng.uniform(-0.5, 0.5, batch)
    z0[:, 2:] = rng.uniform(-0.6, 0.6, (batch, n))
    act0 = np.zeros((batch, 6))
    act0[:, 0] = params.b
    act0[:, 1] = rng.uniform(-0.2, 0.2, batch)
    act0[:, 5] = rng.uniform(-1.0, 1.0, batch)
    stepper = Stepper(params)
    counts = np.full(batch, substeps, dtype=np.int64)
    z, act = z0.copy(), act0.copy()

    def run() -> None:
        # Restart from the initial states so that every call does the same work.
        z[:] = z0
        act[:] = act0
        stepper.step(z, act, DT, counts)

    return run


def measure(quick: bool) -> list[dict[str, Any]]:
    """Time every (threads, n, batch, substeps) case; rows for the CSV."""
    ns = (1, 3, 8, 32) if quick else NS
    batches = (1, 64, 4096) if quick else BATCHES
    cases = [(n, batch, substeps_per_call(batch)) for n in ns for batch in batches]
    cases += [(n, 1, 1) for n in ns]
    rows: list[dict[str, Any]] = []
    for threads in (1, None):
        in_force = set_threads(threads)
        if threads is None and in_force == 1:
            break
        runs = [make_case(n, batch, substeps) for n, batch, substeps in cases]
        seconds = best_of_rounds(
            runs,
            rounds=2 if quick else 3,
            min_total=0.01 if quick else 0.03,
            clock=time.perf_counter,
        )
        for (n, batch, substeps), per_call in zip(cases, seconds, strict=True):
            work = batch * substeps
            rows.append(
                dict(
                    threads=in_force,
                    n=n,
                    batch=batch,
                    substeps_per_call=substeps,
                    seconds_per_call=per_call,
                    substeps_per_second=work / per_call,
                    ns_per_substep_per_state=1e9 * per_call / work,
                )
            )
    set_threads(None)
    return rows


def _lookup(rows: list[dict[str, Any]], **keys: Any) -> dict[str, Any] | None:
    for row in rows:
        if all(row[key] == value for key, value in keys.items()):
            return row
    return None


def plot(rows: list[dict[str, Any]], path: Path) -> Path:
    """Left: cost against batch size per n; right: cost against n for three batch sizes."""
    plt = pyplot()
    fig, (ax_batch, ax_n) = plt.subplots(1, 2, figsize=(12, 4.6))
    thread_counts = sorted({row["threads"] for row in rows})
    ns = sorted({row["n"] for row in rows})
    shown_ns = [n for n in ns if n in (1, 3, 8, 32)] or ns
    for color, n in enumerate(shown_ns):
        for threads in thread_counts:
            points = sorted(
                (row["batch"], row["ns_per_substep_per_state"])
                for row in rows
                if row["n"] == n
                and row["threads"] == threads
                and row["substeps_per_call"] == substeps_per_call(row["batch"])
            )
            x, y = np.array(points).T
            ax_batch.loglog(
                x,
                y,
                color=f"C{color}",
                marker="o",
                ms=3,
                ls="-" if threads == 1 else "--",
                label=f"n = {n}, {threads} thread{'s' if threads > 1 else ''}",
            )
    ax_batch.set_xlabel("batch size B (states per call)")
    ax_batch.set_ylabel("ns per substep per state")
    ax_batch.set_title("RK4 kernel cost against batch size")
    ax_batch.grid(True, which="major", alpha=0.3)
    ax_batch.legend(fontsize=7, ncol=2)
    series = [("B = 1, 1 substep per call", 1, 1, 1)]
    series += [("B = 1, 64 substeps per call", 1, 64, 1)]
    series += [(f"B = 4096, {threads} thread(s)", 4096, 1, threads) for threads in thread_counts]
    for label, batch, substeps, threads in series:
        points = [
            (row["n"], row["ns_per_substep_per_state"])
            for row in rows
            if row["batch"] == batch
            and row["substeps_per_call"] == substeps
            and row["threads"] == threads
        ]
        if points:
            x, y = np.array(sorted(points)).T
            ax_n.loglog(x, y, marker="o", ms=3, label=label)
    reference = _lookup(rows, n=2, batch=4096, substeps_per_call=1, threads=1)
    if reference is not None:
        grid = np.array(ns, dtype=float)
        ax_n.loglog(
            grid,
            reference["ns_per_substep_per_state"] * (grid + 2) / 4,
            "k:",
            lw=1,
            label="proportional to n + 2 (through n = 2, B = 4096)",
        )
    ax_n.set_xlabel("number of trailers n")
    ax_n.set_ylabel("ns per substep per state")
    ax_n.set_title("RK4 kernel cost against n (O(n) field)")
    ax_n.grid(True, which="major", alpha=0.3)
    ax_n.legend(fontsize=7)
    fig.suptitle(f"dynamics.Stepper, default convoy, mass moving ({machine_note()})", fontsize=10)
    return save_figure(fig, path)


def summary(rows: list[dict[str, Any]]) -> list[str]:
    """The headline figures: n = 3 single state and B = 4096, and the n = 32 / n = 2 ratio."""
    lines = []
    for threads in sorted({row["threads"] for row in rows}):
        for batch, substeps in ((1, 1), (1, 64), (4096, 1)):
            row = _lookup(rows, n=3, batch=batch, substeps_per_call=substeps, threads=threads)
            if row is not None:
                lines.append(
                    f"n = 3, B = {batch:5d}, {substeps:2d} substeps/call, {threads} thread(s): "
                    f"{row['substeps_per_second'] / 1e6:6.2f} M substeps/s, "
                    f"{row['ns_per_substep_per_state']:8.1f} ns per substep per state"
                )
        small = _lookup(rows, n=2, batch=4096, substeps_per_call=1, threads=threads)
        large = _lookup(rows, n=32, batch=4096, substeps_per_call=1, threads=threads)
        if small and large:
            ratio = large["ns_per_substep_per_state"] / small["ns_per_substep_per_state"]
            lines.append(
                f"cost(n = 32) / cost(n = 2) at B = 4096, {threads} thread(s): {ratio:.2f}"
            )
    return lines


def main(argv: list[str] | None = None) -> int:
    args = parse_command(
        "python -m benchmarks.kernel_cost", __doc__, "n in (1, 3, 8, 32), B in (1, 64, 4096)", argv
    )
    start = time.perf_counter()
    rows = measure(args.quick)
    write_csv(args.results / "kernel_cost.csv", rows)
    for line in summary(rows):
        print(line)
    path = plot(rows, args.images / "bench_kernel_cost.png")
    report_written(f"{args.results / 'kernel_cost.csv'} and {path}", start)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
