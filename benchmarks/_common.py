"""Shared pieces of the benchmark commands: scenes, CPU timing, output paths, CSV, charts.

The scenes use the default :class:`dynamics.ConvoyParams` with the moving mass at
rest at the middle of its rail, so the energy is conserved (physics.md section
9 with s_dot = s_ddot = 0) and every integrator, the energy-preserving one
included, solves the same problem. States are scaled so that ``|u| = 1``: by the
homogeneity of physics.md section 6 any other speed is a change of time unit.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import os
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dynamics import ConvoyParams, _kernel

ROOT = Path(__file__).resolve().parent.parent
#: Where the commands write by default: nothing git tracks is rewritten unless asked
#: (``--results benchmarks/results --images docs/img`` refreshes the committed figures).
RESULTS = Path("out") / "benchmarks" / "results"
IMAGES = Path("out") / "benchmarks" / "img"

SCENES = ("forward", "reversing")
"""forward: a zig-zag convoy driving forward and straightening (stable node, section 7).
reversing: a nearly straight convoy backing up (unstable node): it jackknifes, the cart
spins round and the convoy ends up driving forward."""


def scene_state(scene: str, n: int) -> np.ndarray:
    """Initial reduced state (u, omega, alpha_1..alpha_n) of a scene."""
    z0 = np.zeros(n + 2)
    if scene == "forward":
        z0[0], z0[1] = 1.0, 0.3
        z0[2:] = 0.4 * (-1.0) ** np.arange(n)
    elif scene == "reversing":
        z0[0], z0[1] = -1.0, 0.01
        if n > 0:
            z0[2] = 0.01
    else:
        raise ValueError(f"unknown scene {scene!r}; expected one of {SCENES}")
    return z0


def scene_params(n: int) -> ConvoyParams:
    """Default convoy with n trailers."""
    return ConvoyParams(n_trailers=n)


def field_for_scipy(
    params: ConvoyParams, s: float = 0.0
) -> Callable[[float, np.ndarray], np.ndarray]:
    """dz/dt(t, z) for ``solve_ivp``: the jitted kernel with the validation layer skipped.

    scipy gets the same compiled field as our integrators and no per-call checks,
    so the comparison measures the integrators, not our input validation.
    """
    packed = _kernel.pack_params(params)
    act = np.array([[params.b, s, 0.0, 0.0, 0.0, 0.0]])
    n = params.n_trailers
    rhs_batch = _kernel.rhs_batch

    def field(t: float, z: np.ndarray) -> np.ndarray:
        return rhs_batch(packed, z.reshape(1, -1), act, n, False)[0]

    return field


def cpu_seconds_once(
    run: Callable[[], Any], min_total: float, clock: Callable[[], float] = time.process_time
) -> float:
    """Seconds per call of ``run`` on ``clock``, averaged over calls filling ``min_total``."""
    calls = 0
    start = clock()
    while True:
        run()
        calls += 1
        elapsed = clock() - start
        if elapsed >= min_total:
            return elapsed / calls


def best_of_rounds(
    runs: Sequence[Callable[[], Any]],
    rounds: int = 3,
    min_total: float = 0.03,
    clock: Callable[[], float] = time.process_time,
) -> list[float]:
    """Seconds per call of each run on ``clock``, the best over ``rounds`` interleaved passes.

    On a shared virtual machine the speed of a core drifts by factors of several for
    seconds at a time; timing every case once per pass, and keeping each case's
    best pass, spreads those slow spells over all cases instead of a few. CPU
    time (the default) counts every thread of the process: use wall time
    (``time.perf_counter``) for the throughput of multithreaded runs.
    """
    warm_up()
    for run in runs:
        run()
    best = [float("inf")] * len(runs)
    for _ in range(rounds):
        for index, run in enumerate(runs):
            best[index] = min(best[index], cpu_seconds_once(run, min_total, clock))
    return best


def warm_up(seconds: float = 0.3) -> None:
    """Spin for a while so that the core is at speed before anything is timed."""
    start = time.process_time()
    values = np.linspace(0.0, 1.0, 10_000)
    while time.process_time() - start < seconds:
        np.sin(values).sum()


def write_csv(path: Path, rows: Sequence[dict[str, Any]]) -> Path:
    """Write dict rows (same keys) to CSV atomically; floats in repr precision."""
    path.parent.mkdir(parents=True, exist_ok=True)
    # A temporary name in the same folder, then a rename: a reader never sees half a file.
    partial = path.with_name(f".{path.name}.partial")
    with partial.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0].keys()))
        writer.writeheader()
        writer.writerows(rows)
    partial.replace(path)
    return path


def pyplot() -> Any:
    """matplotlib.pyplot on the Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def set_threads(threads: int | None) -> int:
    """Set numba's thread count (None: all cores); returns the count in force.

    The RK4 kernel runs chunks of rows in parallel. For one state that buys nothing
    and the idle worker's spin-wait costs CPU time, so single-state comparisons
    (with scipy, which is single-threaded) run on one thread.
    """
    import numba

    # numba fills its config module at import time: mypy cannot see the attribute.
    all_cores = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]
    numba.set_num_threads(all_cores if threads is None else threads)
    return int(numba.get_num_threads())


@contextlib.contextmanager
def one_thread() -> Iterator[None]:
    """Run the block on one numba thread (see :func:`set_threads`), then restore the count."""
    import numba

    previous = numba.get_num_threads()
    set_threads(1)
    try:
        yield
    finally:
        set_threads(previous)


def machine_note() -> str:
    """One line naming the machine, for chart footers and CSV headers."""
    import platform

    return f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs"


def parse_command(
    prog: str,
    description: str | None,
    quick_help: str,
    argv: list[str] | None,
    results_help: str = "CSV folder",
) -> argparse.Namespace:
    """The options every benchmark command takes: ``--quick``, ``--results``, ``--images``.

    Args:
        prog: The command, e.g. ``python -m benchmarks.stability``.
        description: Help text (the module's docstring).
        quick_help: What ``--quick`` cuts.
        argv: Arguments (None: ``sys.argv[1:]``).
        results_help: Help for ``--results``.

    Returns:
        The parsed arguments.
    """
    parser = argparse.ArgumentParser(
        prog=prog, description=description, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--quick", action="store_true", help=quick_help)
    parser.add_argument("--results", type=Path, default=RESULTS, help=results_help)
    parser.add_argument("--images", type=Path, default=IMAGES, help="PNG folder")
    return parser.parse_args(argv)


def save_figure(fig: Any, path: Path, dpi: int = 90) -> Path:
    """Lay out, write atomically (creating the folder) and close a matplotlib figure."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f".{path.name}.partial")
    fig.savefig(partial, dpi=dpi, format=path.suffix.lstrip(".") or "png")
    plt.close(fig)
    partial.replace(path)
    return path


def report_written(what: str, start: float) -> None:
    """Print what a command wrote and how long it took since ``start`` (perf_counter)."""
    print(f"wrote {what} in {time.perf_counter() - start:.0f} s")
