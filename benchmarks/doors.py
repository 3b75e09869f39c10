"""Environment steps per second through every door to the kernel, in one run.

Run with ``python -m benchmarks.doors [--quick] [--results DIR] [--images DIR]``.

Trailer_env/Reverse-v1, n = 3 trailers, default fidelity, one numba thread (and one
torch thread), at N = 1, 16, 256, 4096 environments (``--quick``: N = 1, 16, shorter
rounds). Actions are float32, drawn beforehand from the door's action space (a
bank of batches stepped in turn), except where the door draws them itself (RLlib).
Each door resets the way it does in use:

* ``native``: ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point",
  n_trailers=3)``, ``step(actions)``; its own autoreset (next step);
* ``sb3``: :class:`trailer_env.sb3.ConvoySB3VecEnv`, ``step(actions)``; resets within
  the step, as SB3 expects (terminal observation in the infos);
* ``sync``: Gymnasium's ``SyncVectorEnv`` (``vectorization_mode="sync"``): N
  ``gym.make`` envs stepped in a Python loop, Gymnasium's autoreset;
* ``async``: Gymnasium's ``AsyncVectorEnv`` (``vectorization_mode="async"``), one process
  per env, so only N = 1 and 16 (the other sizes are reported as not measured);
* ``torchrl``: ``torchrl.envs.GymWrapper`` over the native vector env built with
  ``autoreset_mode="disabled"``; times ``env.step_and_maybe_reset(td)`` with the
  pre-made actions written into ``td["action"]`` (TorchRL resets the done rows
  through the env's ``reset_mask``);
* ``rllib``: RLlib's ``SingleAgentEnvRunner`` built locally (no Ray cluster, no
  remote runners) from a ``PPOConfig`` whose env is the native vector env
  (``gym_env_vectorize_mode="vector_entry_point"``, ``num_envs_per_env_runner=N``, the
  env creator of ``agents.training.rllib``); times ``runner.sample(num_timesteps=...,
  random_actions=True)``: RLlib draws the actions from the action space each step and
  builds its episodes, both timed;
* ``single``: one ``gym.make(id, n_trailers=3)`` env stepped N times in a row, reset
  when an episode ends; measured at N = 1 only, the reference row there;
* ``bare``: one block-vectorised RK4 substep of N states of the same model
  (:func:`benchmarks.throughput.bare_substep_runner`): env-substeps per second, the
  floor every door is compared with (it has no actuator, observations, rewards or
  resets).

Timing: wall clock; every case is built (and compiled) first, then timed once per
round for at least ``min_time`` seconds, over a few interleaved rounds, keeping its
best round, so that a slow spell of a shared machine hits all cases rather than a few.
For each door and N: env steps per second, ns per env step, and the ratios of its
throughput to the native env's and to the bare kernel's at the same N (both measured
in the same run). A door whose optional dependency (torchrl, ray) is missing is
reported as skipped, with the reason.

A run writes under ``--results``/``--images`` (default ``out/benchmarks/``):
``doors.csv``, ``doors.md`` and ``bench_doors.png``; the committed outputs would be
``benchmarks/results/doors.csv``, ``benchmarks/results/doors.md`` and
``docs/img/bench_doors.png``.
"""

from __future__ import annotations

import importlib
import math
import os
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from agents.envs import HEADLINE_ENV_ID
from benchmarks._common import (
    machine_note,
    parse_command,
    pyplot,
    report_written,
    save_figure,
    set_threads,
    warm_up,
    write_csv,
)

ENV_ID = HEADLINE_ENV_ID
N_TRAILERS = 3
SIZES = (1, 16, 256, 4096)
QUICK_SIZES = (1, 16)
ACTION_BANK = 16
#: A timed chunk holds at most this many env steps (it doubles from one call up to 1000).
CHUNK_STEPS = 65536

#: run(calls) -> env steps done: ``calls`` calls of the door (each N env steps, or about).
Runner = Callable[[int], int]


@dataclass(frozen=True)
class Door:
    """One way into the environment: how to build it at N envs, and where it applies."""

    key: str
    label: str
    build: Callable[[int, int], tuple[Runner, Callable[[], None]]]  # (N, seed) -> run, close
    requires: tuple[str, ...] = ()  # optional top-level modules
    sizes: tuple[int, ...] | None = None  # None: every N
    not_measured: str = ""  # the reason given at the other sizes ({n}: N, {cpus}: CPUs)


def _float32_batches(space: gym.spaces.Space[Any], count: int) -> list[np.ndarray]:
    return [np.asarray(space.sample(), dtype=np.float32) for _ in range(count)]


def _no_close() -> None:
    return None


def _import_trailer_env() -> None:
    importlib.import_module("trailer_env")


def native_door(num_envs: int, seed: int) -> tuple[Runner, Callable[[], None]]:
    """The native vector env, ``step(actions)``."""
    _import_trailer_env()
    envs = gym.make_vec(
        ENV_ID, num_envs=num_envs, vectorization_mode="vector_entry_point", n_trailers=N_TRAILERS
    )
    return _vector_runner(envs, num_envs, seed)


def _cycling(envs: Any, actions: list[np.ndarray], num_envs: int) -> Runner:
    """A runner stepping ``envs`` through the pre-drawn ``actions`` in a cycle."""
    cursor = 0

    def run(calls: int) -> int:
        nonlocal cursor
        for _ in range(calls):
            envs.step(actions[cursor])
            cursor = (cursor + 1) % len(actions)
        return calls * num_envs

    return run


def _vector_runner(envs: Any, num_envs: int, seed: int) -> tuple[Runner, Callable[[], None]]:
    envs.action_space.seed(seed)
    actions = _float32_batches(envs.action_space, ACTION_BANK)
    envs.reset(seed=seed)
    return _cycling(envs, actions, num_envs), envs.close


def sb3_door(num_envs: int, seed: int) -> tuple[Runner, Callable[[], None]]:
    """:class:`trailer_env.sb3.ConvoySB3VecEnv`, ``step(actions)``."""
    from trailer_env.sb3 import ConvoySB3VecEnv

    envs = ConvoySB3VecEnv(ENV_ID, num_envs=num_envs, n_trailers=N_TRAILERS)
    envs.seed(seed)
    envs.action_space.seed(seed)
    actions = [np.stack(_float32_batches(envs.action_space, num_envs)) for _ in range(ACTION_BANK)]
    envs.reset()
    return _cycling(envs, actions, num_envs), envs.close


def gymnasium_door(mode: str) -> Callable[[int, int], tuple[Runner, Callable[[], None]]]:
    """Gymnasium's own vector env of ``mode`` ("sync" or "async") over ``gym.make`` envs."""

    def build(num_envs: int, seed: int) -> tuple[Runner, Callable[[], None]]:
        _import_trailer_env()
        envs = gym.make_vec(
            ENV_ID, num_envs=num_envs, vectorization_mode=mode, n_trailers=N_TRAILERS
        )
        return _vector_runner(envs, num_envs, seed)

    return build


def torchrl_door(num_envs: int, seed: int) -> tuple[Runner, Callable[[], None]]:
    """``torchrl.envs.GymWrapper`` over the native vector env, ``step_and_maybe_reset``."""
    import torch
    from torchrl.envs import GymWrapper

    _import_trailer_env()
    torch.set_num_threads(1)
    venv = gym.make_vec(
        ENV_ID,
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        autoreset_mode="disabled",
        n_trailers=N_TRAILERS,
    )
    env = GymWrapper(venv)
    env.set_seed(seed)
    venv.action_space.seed(seed)
    actions = [torch.as_tensor(a) for a in _float32_batches(venv.action_space, ACTION_BANK)]
    td = env.reset()
    cursor = 0

    def run(calls: int) -> int:
        nonlocal cursor, td
        for _ in range(calls):
            td["action"] = actions[cursor]
            _, td = env.step_and_maybe_reset(td)
            cursor = (cursor + 1) % ACTION_BANK
        return calls * num_envs

    return run, env.close


def rllib_door(num_envs: int, seed: int) -> tuple[Runner, Callable[[], None]]:
    """RLlib's ``SingleAgentEnvRunner`` over the native vector env, ``sample(random_actions)``."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.env.single_agent_env_runner import SingleAgentEnvRunner

    from agents.training.rllib import register_trailer_env

    config = (
        PPOConfig()
        .environment(
            env=register_trailer_env(),
            env_config={"env_id": ENV_ID, "n_trailers": N_TRAILERS},
        )
        .env_runners(
            num_env_runners=0,
            num_envs_per_env_runner=num_envs,
            gym_env_vectorize_mode="vector_entry_point",
        )
        .debugging(seed=seed)
    )
    runner = SingleAgentEnvRunner(config=config)

    def run(calls: int) -> int:
        episodes = runner.sample(num_timesteps=calls * num_envs, random_actions=True)
        return sum(len(episode) for episode in episodes)

    return run, runner.stop


def single_door(num_envs: int, seed: int) -> tuple[Runner, Callable[[], None]]:
    """One ``gym.make`` env stepped ``num_envs`` times per call, reset when an episode ends."""
    _import_trailer_env()
    env = gym.make(ENV_ID, n_trailers=N_TRAILERS)
    env.action_space.seed(seed)
    bank = 4096
    actions = _float32_batches(env.action_space, bank)
    env.reset(seed=seed)
    cursor = 0

    def run(calls: int) -> int:
        nonlocal cursor
        for _ in range(calls * num_envs):
            _, _, terminated, truncated, _ = env.step(actions[cursor])
            cursor = (cursor + 1) % bank
            if terminated or truncated:
                env.reset()
        return calls * num_envs

    return run, env.close


def bare_door(num_envs: int, seed: int) -> tuple[Runner, Callable[[], None]]:
    """One block-vectorised RK4 substep of ``num_envs`` states (the physics alone)."""
    from benchmarks.throughput import bare_substep_runner

    with warnings.catch_warnings():  # it builds Reverse-v0's states: the same model as v1's
        warnings.simplefilter("ignore", DeprecationWarning)
        substep = bare_substep_runner(N_TRAILERS, num_envs, seed)

    def run(calls: int) -> int:
        substep(calls)
        return calls * num_envs

    return run, _no_close


DOORS = (
    Door("native", "native vector env", native_door),
    Door("sb3", "SB3 adapter (ConvoySB3VecEnv)", sb3_door),
    Door("sync", "Gymnasium SyncVectorEnv", gymnasium_door("sync")),
    Door(
        "async",
        "Gymnasium AsyncVectorEnv",
        gymnasium_door("async"),
        sizes=(1, 16),
        not_measured="one process per env ({n} processes on {cpus} CPUs)",
    ),
    Door("torchrl", "TorchRL GymWrapper", torchrl_door, requires=("torch", "torchrl")),
    Door("rllib", "RLlib SingleAgentEnvRunner", rllib_door, requires=("ray",)),
    Door(
        "single",
        "single env (gym.make), N steps in a row",
        single_door,
        sizes=(1,),
        not_measured="the reference row is N = 1 (N steps in a row cost N times one)",
    ),
    Door("bare", "bare RK4 substep (env-substeps)", bare_door),
)


def missing_dependency(door: Door) -> str:
    """Why ``door`` cannot be measured here ("" when its optional modules import)."""
    for module in door.requires:
        try:
            importlib.import_module(module)
        except ImportError as error:
            return f"skipped: {module} not installed ({type(error).__name__})"
    return ""


@dataclass
class Case:
    """One door at one N: its runner once built, its best rate so far."""

    door: Door
    num_envs: int
    note: str = ""
    run: Runner | None = None
    close: Callable[[], None] = _no_close
    best: float = 0.0
    build_seconds: float = float("nan")
    failed: str = ""

    @property
    def measured(self) -> bool:
        return self.run is not None and not self.failed


def plan(sizes: tuple[int, ...], doors: tuple[Door, ...] = DOORS) -> list[Case]:
    """Every (door, N) case, with the reason for those that are not measured."""
    cases = []
    for door in doors:
        missing = missing_dependency(door)
        for size in sizes:
            note = missing
            if not note and door.sizes is not None and size not in door.sizes:
                reason = door.not_measured.format(n=size, cpus=os.cpu_count())
                note = f"not measured: {reason}"
            cases.append(Case(door, size, note=note))
    return cases


def build(case: Case, seed: int = 0) -> None:
    """Build ``case``'s runner and run it twice (compile, warm caches); print a line."""
    start = time.perf_counter()
    try:
        case.run, case.close = case.door.build(case.num_envs, seed)
        case.run(2)
    except Exception as error:  # a door that breaks is reported, not fatal to the table
        case.failed = f"failed: {type(error).__name__}: {error}".splitlines()[0][:200]
        case.run = None
    case.build_seconds = time.perf_counter() - start
    status = case.failed or f"built in {case.build_seconds:.1f} s"
    print(f"  {case.door.key:8s} N = {case.num_envs:5d}: {status}", flush=True)


def time_round(case: Case, min_time: float) -> None:
    """Run ``case`` for at least ``min_time`` s of wall time and keep its best rate."""
    assert case.run is not None
    limit = max(1, min(1000, CHUNK_STEPS // case.num_envs))
    steps, chunk, start = 0, 1, time.perf_counter()
    while (elapsed := time.perf_counter() - start) < min_time:
        steps += case.run(chunk)
        chunk = min(2 * chunk, limit)
    case.best = max(case.best, steps / elapsed)


def measure(
    quick: bool, doors: tuple[Door, ...] = DOORS, sizes: tuple[int, ...] | None = None
) -> list[dict[str, Any]]:
    """Build every case, time them in interleaved rounds, return one row per (door, N)."""
    sizes = sizes or (QUICK_SIZES if quick else SIZES)
    min_time = 0.1 if quick else 1.0
    rounds = 2 if quick else 3
    set_threads(1)
    cases = plan(sizes, doors)
    print(f"building {sum(not case.note for case in cases)} cases", flush=True)
    for case in cases:
        if case.note:
            print(f"  {case.door.key:8s} N = {case.num_envs:5d}: {case.note}", flush=True)
        else:
            build(case)
    warm_up()
    timed = [case for case in cases if case.measured]
    for index in range(rounds):
        round_start = time.perf_counter()
        for case in timed:
            time_round(case, min_time)
        print(f"round {index + 1}/{rounds}: {time.perf_counter() - round_start:.0f} s", flush=True)
    for case in cases:
        try:
            case.close()
        except Exception as error:  # closing is not measured; say so and go on
            print(f"  {case.door.key} N = {case.num_envs}: close failed ({error})")
    return rows_of(cases)


def rows_of(cases: list[Case]) -> list[dict[str, Any]]:
    """CSV rows: rates, ns per env step, ratios to the native env and the bare kernel."""
    rates = {(case.door.key, case.num_envs): case.best for case in cases if case.measured}
    rows = []
    for case in cases:
        rate = rates.get((case.door.key, case.num_envs), float("nan"))
        native = rates.get(("native", case.num_envs), float("nan"))
        bare = rates.get(("bare", case.num_envs), float("nan"))
        rows.append(
            dict(
                door=case.door.key,
                label=case.door.label,
                num_envs=case.num_envs,
                measured=case.measured,
                steps_per_second=rate,
                ns_per_env_step=1e9 / rate if rate > 0 else float("nan"),
                ratio_native=rate / native,
                ratio_bare=rate / bare,
                note=case.failed or case.note,
            )
        )
        if case.measured:
            print(
                f"{case.door.key:8s} N = {case.num_envs:5d}: {rate:12,.0f} env steps/s "
                f"{1e9 / rate:9,.0f} ns  {rate / native:6.2f}x native  {rate / bare:6.2f}x bare"
            )
        else:
            print(f"{case.door.key:8s} N = {case.num_envs:5d}: {case.failed or case.note}")
    return rows


def load_note() -> str:
    """The machine and its load average (1, 5, 15 min) when called."""
    load = ", ".join(f"{value:.2f}" for value in os.getloadavg())
    return f"{machine_note()}, load average {load}"


def _ratio(value: float) -> str:
    if math.isnan(value):
        return ""
    return f"{value:.2f}x" if value >= 0.095 else f"{value:.3f}x"


def markdown_table(rows: list[dict[str, Any]], note: str) -> str:
    """ns per env step per door and N, then one table per N with rates and ratios."""
    sizes = sorted({row["num_envs"] for row in rows})
    doors = list(dict.fromkeys(row["door"] for row in rows))
    by_key = {(row["door"], row["num_envs"]): row for row in rows}
    labels = {row["door"]: row["label"] for row in rows}
    lines = [
        f"Reverse-v1, n = {N_TRAILERS}, default fidelity, one numba thread, float32 actions; "
        f"ns per env step (wall clock, best of interleaved rounds). {note}.",
        "",
        "| door | " + " | ".join(f"N = {size}" for size in sizes) + " |",
        "|---|" + "---|" * len(sizes),
    ]
    for door in doors:
        cells = []
        for size in sizes:
            row = by_key[(door, size)]
            cells.append(f"{row['ns_per_env_step']:,.0f}" if row["measured"] else "-")
        lines.append(f"| {labels[door]} | " + " | ".join(cells) + " |")
    for size in sizes:
        lines += [
            "",
            f"N = {size}:",
            "",
            "| door | env steps/s | ns per env step | / native | / bare kernel | note |",
            "|---|---|---|---|---|---|",
        ]
        for door in doors:
            row = by_key[(door, size)]
            if row["measured"]:
                lines.append(
                    f"| {labels[door]} | {row['steps_per_second']:,.0f} "
                    f"| {row['ns_per_env_step']:,.0f} | {_ratio(row['ratio_native'])} "
                    f"| {_ratio(row['ratio_bare'])} | {row['note']} |"
                )
            else:
                lines.append(f"| {labels[door]} | | | | | {row['note']} |")
    return "\n".join(lines) + "\n"


def plot(rows: list[dict[str, Any]], path: Path, note: str) -> Path:
    """Env steps per second against N per door, log-log; the bare kernel as a line."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(10, 5))
    doors = list(dict.fromkeys(row["door"] for row in rows))
    for index, door in enumerate(doors):
        points = sorted(
            (row["num_envs"], row["steps_per_second"])
            for row in rows
            if row["door"] == door and row["measured"]
        )
        if not points:
            continue
        x, y = np.array(points).T
        label = next(row["label"] for row in rows if row["door"] == door)
        if door == "bare":
            ax.loglog(x, y, "k--", lw=1.5, label=label)
        else:
            ax.loglog(x, y, "o-", color=f"C{index}", label=label)
    ax.set_xlabel("number of environments N")
    ax.set_ylabel("env steps per second (wall clock)")
    ax.set_title(
        f"Reverse-v1, n = {N_TRAILERS}, one numba thread: every door to the kernel", fontsize=10
    )
    ax.grid(True, which="major", alpha=0.3)
    sizes = sorted({row["num_envs"] for row in rows})
    ax.set_xticks(sizes, [str(size) for size in sizes])
    ax.minorticks_off()
    ax.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.text(0.5, 0.005, note, ha="center", fontsize=7, color="0.4")
    return save_figure(fig, path)


def main(argv: list[str] | None = None) -> int:
    args = parse_command(
        "python -m benchmarks.doors",
        __doc__,
        "N = 1 and 16 only, two short rounds (about 30 s)",
        argv,
        results_help="CSV / markdown folder",
    )
    start = time.perf_counter()
    before = os.getloadavg()
    rows = measure(args.quick)
    note = f"{load_note()} (at the start {before[0]:.2f})"
    csv_path = write_csv(args.results / "doors.csv", rows)
    table = markdown_table(rows, note)
    (args.results / "doors.md").write_text(table)
    print(table)
    path = plot(rows, args.images / "bench_doors.png", note)
    report_written(f"{csv_path}, {args.results / 'doors.md'} and {path}", start)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
