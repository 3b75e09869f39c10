"""Environment throughput against Gymnasium's classic-control peers, in one run.

Run with ``python -m benchmarks.throughput [--quick]``.

Measured on wall-clock time (the best of a few interleaved rounds), with
actions drawn beforehand so that sampling is not timed:

* single env: steps per second of the convoy's Reverse-v0 (n = 2, default
  fidelity) against Acrobot-v1 and CartPole-v1, all through ``gym.make`` (the same
  default wrappers: PassiveEnvChecker, OrderEnforcing, TimeLimit), resetting
  whenever an episode ends; the convoy once with numba's default thread count and
  once on one thread;
* vector env: environment steps per second (N per call) of Reverse-v0's vector env
  against Gymnasium's numpy CartPole vector env
  (``gym.make_vec("CartPole-v1", vectorization_mode="vector_entry_point")``) for
  N = 64 .. 16384, the convoy on numba's default threads and on one;
* bare substep: one block-vectorised RK4 substep of Reverse-v0's model (n = 3,
  N = 4096, one thread, ``dynamics.Stepper`` on reset states): environment-substeps
  per second, the floor the vector env step is measured against (the step adds the
  actuator, the auto rule, the fold test, observations, reward and termination);
* cost against n: single-env and vector-env (N = 4096) steps per second of
  Reverse-v0 for n = 1 .. 32, on one numba thread (stable on a shared machine), at
  the default fidelity (whose substeps grow with n to hold the tolerance, see
  :mod:`trailer_env.substeps`) and at one fixed substep (the same physics step count
  for every n: the kernel's cost). The mean substeps per step of each convoy case
  is counted separately, outside the timed runs.

Every case is timed once per round, over three rounds, and keeps its best round, so
that a slow spell of a shared machine hits all cases rather than a few. Why one
thread for single envs: the RK4 kernel runs chunks of rows on numba's threads; one
row leaves the second thread spinning at the barrier, and when another process
wants that core each step can wait a scheduler time slice (measured: 8 ms).

``trailer_env`` is imported lazily: without it (or before it registers
Reverse-v0) only the peers are measured.

A run writes under ``--results``/``--images`` (default ``out/benchmarks/``); the
committed outputs: ``benchmarks/results/throughput.csv``, ``benchmarks/results/throughput.md``
(the table of docs/benchmarks.md, "Speed and accuracy") and ``docs/img/bench_throughput.png``.
"""

from __future__ import annotations

import argparse
import importlib
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from benchmarks._common import (
    IMAGES,
    RESULTS,
    machine_note,
    pyplot,
    set_threads,
    warm_up,
    write_csv,
)

PEERS = ("CartPole-v1", "Acrobot-v1")
VECTOR_SIZES = (64, 256, 1024, 4096, 16384)
TRAILER_COUNTS = (1, 2, 4, 8, 16, 32)
SCENE = "Reverse-v0"
ACTION_BANK = 4096


def find_convoy_id(scene: str = SCENE) -> str | None:
    """The registered id of a convoy scene (after importing trailer_env), or None."""
    try:
        importlib.import_module("trailer_env")
    except ImportError:
        return None
    candidates = [
        env_id
        for env_id, spec in gym.registry.items()
        if env_id.split("/")[-1] == scene and "trailer_env" in str(spec.entry_point)
    ]
    return sorted(candidates)[0] if candidates else None


def single_env_runner(env_id: str, seed: int = 0, **kwargs: Any) -> Callable[[int], None]:
    """run(steps): step one ``gym.make`` env with pre-drawn random actions."""
    env = gym.make(env_id, **kwargs)
    env.action_space.seed(seed)
    actions = [env.action_space.sample() for _ in range(ACTION_BANK)]
    env.reset(seed=seed)
    cursor = 0

    def run(steps: int) -> None:
        nonlocal cursor
        for _ in range(steps):
            _, _, terminated, truncated, _ = env.step(actions[cursor])
            cursor = (cursor + 1) % ACTION_BANK
            if terminated or truncated:
                env.reset()

    return run


def vector_env_runner(
    env_id: str, num_envs: int, seed: int = 0, **kwargs: Any
) -> Callable[[int], None]:
    """run(calls): step a ``gym.make_vec`` vector env (its own autoreset)."""
    envs = gym.make_vec(
        env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs
    )
    envs.action_space.seed(seed)
    actions = [envs.action_space.sample() for _ in range(16)]
    envs.reset(seed=seed)
    cursor = 0

    def run(calls: int) -> None:
        nonlocal cursor
        for _ in range(calls):
            envs.step(actions[cursor])
            cursor = (cursor + 1) % len(actions)

    return run


def bare_substep_runner(n: int, num_envs: int, seed: int = 0) -> Callable[[int], None]:
    """run(calls): one RK4 substep of ``num_envs`` Reverse-v0 states (the physics alone)."""
    from dynamics import Stepper

    envs = gym.make_vec(
        find_convoy_id() or SCENE,
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        n_trailers=n,
    )
    envs.reset(seed=seed)
    core = envs.unwrapped.core
    z, act = core.z.copy(), core.act.copy()
    stepper = Stepper(core.params)
    substeps = np.ones(num_envs, dtype=np.int64)
    # A short dt keeps the states where they started, however many calls are timed.
    dt = 1e-6

    def run(calls: int) -> None:
        for _ in range(calls):
            stepper.step(z, act, dt, substeps)

    return run


def mean_substeps(env_id: str, num_envs: int, seed: int = 1, **kwargs: Any) -> float:
    """Mean substeps per environment step over 200 steps under random actions (not timed)."""
    envs = gym.make_vec(
        env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs
    )
    envs.action_space.seed(seed)
    envs.reset(seed=seed)
    core = envs.unwrapped.core
    total = 0
    for _ in range(200):
        envs.step(envs.action_space.sample())
        total += int(core.substeps.sum())
    envs.close()
    return total / (200 * num_envs)


@dataclass
class Case:
    """One throughput measurement: what it is, how to run it, its best rate so far."""

    kind: str
    env: str
    n: int | None
    num_envs: int
    threads: int | None  # None: numba's default
    make: Callable[[], Callable[[int], None]]
    fidelity: str = ""  # "auto" (the default) or "1" (one substep); "" for the peers
    run: Callable[[int], None] | None = None
    best: float = 0.0
    mean_substeps: float = float("nan")


def time_round(case: Case, min_time: float) -> None:
    """Run ``case`` for at least ``min_time`` s and keep its best rate (env steps per second)."""
    set_threads(case.threads)
    if case.run is None:
        case.run = case.make()
        case.run(2)  # compile, warm caches
    units, start = 0, time.perf_counter()
    chunk = 1
    while (elapsed := time.perf_counter() - start) < min_time:
        case.run(chunk)
        units += chunk
        chunk = min(2 * chunk, 1000)
    case.best = max(case.best, units * case.num_envs / elapsed)


def cases(quick: bool) -> list[Case]:
    """Every measurement of the module docstring (the convoy's only where it is registered)."""
    convoy = find_convoy_id()
    out = [Case("single", peer, None, 1, None, partial(single_env_runner, peer)) for peer in PEERS]
    vector = convoy is not None and gym.registry[convoy].vector_entry_point is not None
    if convoy is not None:
        for threads in (None, 1):
            out.append(
                Case(
                    "single",
                    convoy,
                    2,
                    1,
                    threads,
                    partial(single_env_runner, convoy, n_trailers=2),
                    fidelity="auto",
                )
            )
    if vector and convoy is not None:
        out.append(
            Case("substep", convoy, 3, 4096, 1, partial(bare_substep_runner, 3, 4096), fidelity="1")
        )
    for size in (64, 4096) if quick else VECTOR_SIZES:
        out.append(
            Case(
                "vector",
                "CartPole-v1",
                None,
                size,
                None,
                partial(vector_env_runner, "CartPole-v1", size),
            )
        )
        if vector and convoy is not None:
            for threads in (None, 1):
                out.append(
                    Case(
                        "vector",
                        convoy,
                        3,
                        size,
                        threads,
                        partial(vector_env_runner, convoy, size, n_trailers=3),
                        fidelity="auto",
                    )
                )
    if convoy is not None:
        for n in (1, 2, 8, 32) if quick else TRAILER_COUNTS:
            for fidelity in ("auto", "1"):
                settings: dict[str, Any] = {"n_trailers": n}
                if fidelity == "1":
                    settings["fidelity"] = 1
                # One thread: the kernel's threads cannot help one state (see docs/benchmarks.md).
                out.append(
                    Case(
                        "cost_n",
                        convoy,
                        n,
                        1,
                        1,
                        partial(single_env_runner, convoy, **settings),
                        fidelity=fidelity,
                    )
                )
                if vector:
                    out.append(
                        Case(
                            "cost_n",
                            convoy,
                            n,
                            4096,
                            1,
                            partial(vector_env_runner, convoy, 4096, **settings),
                            fidelity=fidelity,
                        )
                    )
    return out


def measure(quick: bool) -> list[dict[str, Any]]:
    """All throughput rows, each the best of interleaved rounds (slow spells hit every case)."""
    min_time = 0.2 if quick else 1.0
    rounds = 2 if quick else 3
    warm_up()
    default_threads = set_threads(None)
    todo = cases(quick)
    for _ in range(rounds):
        for case in todo:
            time_round(case, min_time)
    set_threads(None)
    substeps: dict[tuple[int, str], float] = {}
    for case in todo:
        if case.fidelity and case.n is not None and gym.registry[case.env].vector_entry_point:
            key = (case.n, case.fidelity)
            if key not in substeps:
                kwargs: dict[str, Any] = {"n_trailers": case.n}
                if case.fidelity == "1":
                    kwargs["fidelity"] = 1
                substeps[key] = mean_substeps(case.env, 256, **kwargs)
            case.mean_substeps = substeps[key]
    rows = []
    for case in todo:
        threads = default_threads if case.threads is None else case.threads
        rows.append(
            dict(
                kind=case.kind,
                env=case.env,
                n=case.n,
                num_envs=case.num_envs,
                threads=threads,
                fidelity=case.fidelity,
                mean_substeps=case.mean_substeps,
                steps_per_second=case.best,
            )
        )
        print(
            f"{case.kind:7s} {case.env:22s} n = {case.n!s:4s} N = {case.num_envs:6d} "
            f"threads = {threads} fidelity = {case.fidelity or '-':4s}: "
            f"{case.best:12,.0f} steps/s"
        )
    return rows


def _rate(rows: list[dict[str, Any]], **keys: Any) -> float:
    matches = [row["steps_per_second"] for row in rows if all(row[k] == v for k, v in keys.items())]
    return max(matches) if matches else float("nan")


def targets(rows: list[dict[str, Any]]) -> list[tuple[str, float, str]]:
    """(target, measured ratio, required) for the issue's throughput targets."""
    convoy = next((row["env"] for row in rows if row["env"] not in PEERS), None)
    out: list[tuple[str, float, str]] = []
    if convoy is None:
        return out
    default_threads = max(row["threads"] for row in rows)
    acrobot = _rate(rows, kind="single", env="Acrobot-v1")
    cartpole = _rate(rows, kind="single", env="CartPole-v1")
    for threads in sorted({default_threads, 1}, reverse=True):
        single = _rate(rows, kind="single", env=convoy, threads=threads)
        out.append(
            (
                f"single env Reverse-v0 n = 2 / Acrobot-v1 ({threads} thread(s))",
                single / acrobot,
                ">= 3",
            ),
        )
        out.append(
            (
                f"single env Reverse-v0 n = 2 / CartPole-v1 ({threads} thread(s))",
                single / cartpole,
                "(none)",
            ),
        )
    cartpole_vector = _rate(rows, kind="vector", env="CartPole-v1", num_envs=4096)
    for threads in sorted({default_threads, 1}, reverse=True):
        vector = _rate(rows, kind="vector", env=convoy, num_envs=4096, threads=threads)
        out.append(
            (
                f"vector env N = 4096, n = 3 / CartPole vector env ({threads} thread(s))",
                vector / cartpole_vector,
                ">= 0.12",
            ),
        )
    bare = _rate(rows, kind="substep", env=convoy)
    vector_one = _rate(rows, kind="vector", env=convoy, num_envs=4096, threads=1)
    out.append(
        (
            "vector env step / bare RK4 substep, time per env (N = 4096, n = 3, 1 thread)",
            bare / vector_one,
            "<= 1.5 (at worst 2)",
        ),
    )
    if default_threads > 1:
        for size in VECTOR_SIZES:
            parallel = _rate(
                rows, kind="vector", env=convoy, num_envs=size, threads=default_threads
            )
            serial = _rate(rows, kind="vector", env=convoy, num_envs=size, threads=1)
            if not np.isnan(parallel / serial):
                out.append(
                    (
                        f"vector env N = {size}: {default_threads} threads / 1 thread",
                        parallel / serial,
                        "(measured)",
                    ),
                )
    for num_envs in (1, 4096):
        for fidelity in ("auto", "1"):
            cost_2 = 1.0 / _rate(rows, kind="cost_n", n=2, num_envs=num_envs, fidelity=fidelity)
            cost_32 = 1.0 / _rate(rows, kind="cost_n", n=32, num_envs=num_envs, fidelity=fidelity)
            where = "single env" if num_envs == 1 else "N = 4096"
            what = "default fidelity" if fidelity == "auto" else "1 substep"
            out.append((f"cost n = 32 / cost n = 2 ({where}, {what})", cost_32 / cost_2, "<= 8"))
    return out


def markdown_table(rows: list[dict[str, Any]]) -> str:
    """The table of docs/benchmarks.md: one line per measurement, then the targets."""
    lines = [
        "| kind | env | n | N | threads | fidelity | substeps per step | env steps/s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        n = "" if row["n"] is None else row["n"]
        substeps = "" if np.isnan(row["mean_substeps"]) else f"{row['mean_substeps']:.2f}"
        lines.append(
            f"| {row['kind']} | {row['env']} | {n} | {row['num_envs']} | {row['threads']} "
            f"| {row['fidelity']} | {substeps} | {row['steps_per_second']:,.0f} |"
        )
    lines += ["", "| target | measured | required |", "|---|---|---|"]
    for name, measured, required in targets(rows):
        lines.append(f"| {name} | {measured:.2f} | {required} |")
    return "\n".join(lines) + "\n"


def plot(rows: list[dict[str, Any]], path: Path) -> Path:
    """Single-env bars, vector-env rates against N, cost against n."""
    plt = pyplot()
    fig, (ax_single, ax_vector, ax_n) = plt.subplots(1, 3, figsize=(15, 4.4))
    singles = [row for row in rows if row["kind"] == "single"]
    labels = [
        f"{row['env'].split('/')[-1]}\n{'n = 2, ' if row['n'] else ''}{row['threads']} thr"
        for row in singles
    ]
    ax_single.bar(
        range(len(singles)),
        [row["steps_per_second"] for row in singles],
        color=["C7" if row["env"] in PEERS else "C0" for row in singles],
    )
    ax_single.set_xticks(range(len(singles)), labels, fontsize=8)
    for index, row in enumerate(singles):
        ax_single.annotate(
            f"{row['steps_per_second'] / 1e3:,.0f}k",
            (index, row["steps_per_second"]),
            ha="center",
            va="bottom",
            fontsize=8,
        )
    ax_single.set_ylabel("env steps per second")
    ax_single.set_title("Single env through gym.make")
    series = sorted({(row["env"], row["threads"]) for row in rows if row["kind"] == "vector"})
    for env, threads in series:
        points = sorted(
            (row["num_envs"], row["steps_per_second"])
            for row in rows
            if row["kind"] == "vector" and row["env"] == env and row["threads"] == threads
        )
        x, y = np.array(points).T
        label = env if env in PEERS else f"{env}, n = 3, {threads} thread{'s' * (threads > 1)}"
        ax_vector.loglog(x, y, "s--" if env in PEERS else "o-", label=label)
    bare = [row for row in rows if row["kind"] == "substep"]
    if bare:
        ax_vector.axhline(
            bare[0]["steps_per_second"],
            color="k",
            lw=0.8,
            ls=":",
            label="bare RK4 substep (env-substeps/s), n = 3, 1 thread",
        )
    ax_vector.set_xlabel("number of environments N")
    ax_vector.set_ylabel("env steps per second")
    ax_vector.set_title("Vector env")
    ax_vector.legend(fontsize=8)
    for num_envs, fidelity, style in (
        (1, "auto", "o-"),
        (1, "1", "o:"),
        (4096, "auto", "s-"),
        (4096, "1", "s:"),
    ):
        points = sorted(
            (row["n"], row["steps_per_second"])
            for row in rows
            if row["kind"] == "cost_n"
            and row["num_envs"] == num_envs
            and row["fidelity"] == fidelity
        )
        if points:
            x, y = np.array(points).T
            where = "single env" if num_envs == 1 else "vector env, N = 4096"
            what = "default fidelity" if fidelity == "auto" else "1 substep"
            ax_n.loglog(x, 1e6 / y, style, label=f"{where}, {what}")
    ax_n.set_xlabel("number of trailers n")
    ax_n.set_ylabel("microseconds per env step (1 thread)")
    ax_n.set_title("Cost against n (Reverse-v0)")
    if ax_n.get_legend_handles_labels()[0]:
        ax_n.legend(fontsize=8)
    for ax in (ax_single, ax_vector, ax_n):
        ax.grid(True, which="major", alpha=0.3)
    fig.suptitle(f"Throughput, wall clock ({machine_note()})", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.throughput",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--quick", action="store_true", help="shorter timings, fewer sizes")
    parser.add_argument("--results", type=Path, default=RESULTS, help="CSV / markdown folder")
    parser.add_argument("--images", type=Path, default=IMAGES, help="PNG folder")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    if find_convoy_id() is None:
        print(f"trailer_env does not register {SCENE} (yet): measuring the peers only")
    rows = measure(args.quick)
    write_csv(args.results / "throughput.csv", rows)
    table = markdown_table(rows)
    (args.results / "throughput.md").write_text(table)
    print(table)
    path = plot(rows, args.images / "bench_throughput.png")
    print(
        f"wrote {args.results}/throughput.csv, throughput.md and {path} "
        f"in {time.perf_counter() - start:.0f} s"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
