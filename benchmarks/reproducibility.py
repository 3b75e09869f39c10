"""What reproduces across CPUs: the protocol's episodes under several code-generation targets.

Run with ``python -m benchmarks.reproducibility [--quick]``.

numba compiles the kernels for the host CPU, and torch and MKL pick their kernels by
the CPU too, so the last bits of a float differ between an AVX2, an AVX-512 and a
generic x86-64 machine. This command measures what that does to the benchmark: it
records the protocol's episodes (:mod:`trailer_env.benchmark`, seeds 1000..1099) of
the zero action, the LQR and every committed agent of each protocol task, once per
*target*, each in a fresh subprocess with its own numba cache:

===========  ==============================================================================
target       environment of the subprocess
===========  ==============================================================================
host-1t      the host CPU, one numba and one torch thread (the reference)
host-2t      the host CPU, two threads
avx2         ``NUMBA_CPU_NAME=haswell``, ``ATEN_CPU_CAPABILITY=avx2``,
             ``MKL_ENABLE_INSTRUCTIONS=AVX2``: code for an AVX2 machine
generic      ``NUMBA_CPU_NAME=generic``, ``ATEN_CPU_CAPABILITY=default``,
             ``MKL_ENABLE_INSTRUCTIONS=SSE4_2``: code for any x86-64
===========  ==============================================================================

and compares every target's episodes with the reference: per episode the outcome
(safe, success, failure, fold, and the length of an episode that did not fail) must be
identical, and the returns agree to :data:`RETURN_RTOL`; a failure at another step is
counted apart (:func:`compare`). The contract this measures, and where a host breaks it,
is written in docs/reliability.md ("What reproduces where");
``tests/benchmarks/test_reproducibility.py`` checks it on the headline task.

Outputs: ``reproducibility.csv`` (one row per target, task and policy) and
``reproducibility.md`` under ``--results``; the raw episodes of each target as JSON
in a temporary folder (``--keep`` keeps them). ``record`` and ``compare`` are the two
halves, for a comparison between two real machines::

    python -m benchmarks.reproducibility record --out here.json
    python -m benchmarks.reproducibility compare here.json there.json
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks._common import RESULTS, machine_note, report_written, write_csv

#: Relative tolerance of an episode's return across targets (see the module docstring):
#: on AVX-512 CPUs without AMX the largest measured difference was 6.2e-5 (a 64 x 64 PPO
#: agent of Reverse-v1, n = 2), a margin of 16. On an AVX-512 CPU with AMX the headline
#: task stays within 7e-5, but other tasks exceed it (up to 1.7e-2 on Coast-v0 n = 2,
#: benchmarks/results/reproducibility.md), so the full run reports a failure there.
RETURN_RTOL = 1e-3
#: Per-episode outcomes that must be identical across targets. An episode's length is one
#: too, except where it ended in a failure: after a policy has lost the unstable convoy,
#: the last-bit differences grow to O(1) before the fold, so when it folds (and its
#: return) is not reproducible, only that it does (:func:`compare`).
OUTCOMES = ("safe", "success", "failed", "jackknifed")
#: Environment of each target's subprocess (added to the caller's).
TARGETS: dict[str, dict[str, str]] = {
    "host-1t": {"NUMBA_NUM_THREADS": "1", "TORCH_THREADS": "1"},
    "host-2t": {"NUMBA_NUM_THREADS": "2", "TORCH_THREADS": "2"},
    "avx2": {
        "NUMBA_CPU_NAME": "haswell",
        "OPENBLAS_CORETYPE": "Haswell",
        "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
        "ATEN_CPU_CAPABILITY": "avx2",
        "MKL_ENABLE_INSTRUCTIONS": "AVX2",
        "NUMBA_NUM_THREADS": "1",
        "TORCH_THREADS": "1",
    },
    "generic": {
        "NUMBA_CPU_NAME": "generic",
        "OPENBLAS_CORETYPE": "Prescott",
        "NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL AVX512_SPR",
        "ATEN_CPU_CAPABILITY": "default",
        "MKL_ENABLE_INSTRUCTIONS": "SSE4_2",
        "NUMBA_NUM_THREADS": "1",
        "TORCH_THREADS": "1",
    },
}
REFERENCE = "host-1t"
#: Baselines recorded on every task (cheap ones: the planners take minutes per task).
BASELINES = ("zero", "lqr")


def task_policies(env_id: str, n: int) -> list[str]:
    """The baselines and every committed model whose card names ``env_id`` and ``n``."""
    from agents.artifacts.shipped import committed_models

    return [*BASELINES, *(path.stem for path in committed_models(env_id, n))]


def record(
    tasks: Sequence[tuple[str, int]], episodes: int, policies: Sequence[str] | None = None
) -> dict[str, Any]:
    """Every policy's episodes on every task, as JSON-ready lists (this process's target)."""
    import numba
    import torch

    from agents.evaluation.results import load_policies
    from trailer_env.benchmark import TEST_SEED, rollout

    threads = int(os.environ.get("TORCH_THREADS", "1"))
    torch.set_num_threads(threads)
    document: dict[str, Any] = {
        "numba_cpu": os.environ.get("NUMBA_CPU_NAME", "host"),
        "numba_threads": numba.get_num_threads(),
        "torch_threads": threads,
        "torch_capability": torch.backends.cpu.get_cpu_capability(),
        "machine": machine_note(),
        "episodes": {},
    }
    for env_id, n in tasks:
        kwargs = {"n_trailers": n}
        specs = list(policies) if policies is not None else task_policies(env_id, n)
        for spec, policy in load_policies(specs, env_id, kwargs):
            results = rollout(policy, env_id, episodes, TEST_SEED, kwargs)
            key = f"{env_id} n={n} {Path(spec).stem}"
            document["episodes"][key] = {
                "returns": results.returns.tolist(),
                "min_margin": results.min_margin.tolist(),
                **{name: getattr(results, name).astype(int).tolist() for name in OUTCOMES},
                "lengths": results.lengths.astype(int).tolist(),
            }
    return document


def compare(reference: Mapping[str, Any], other: Mapping[str, Any]) -> list[dict[str, Any]]:
    """One row per (task, policy) of both documents: outcome changes and return differences.

    An outcome changed where :data:`OUTCOMES` differ, or the length of an episode that
    did not end in a failure. Failed episodes whose length differs are counted apart
    (``failure_times_changed``); their returns, like those of changed outcomes, are left
    out of ``max_rel_return_diff``.
    """
    rows = []
    for key, mine in reference["episodes"].items():
        theirs = other["episodes"].get(key)
        if theirs is None:
            continue
        changed = np.zeros(len(mine["returns"]), dtype=bool)
        for name in OUTCOMES:
            changed |= np.asarray(mine[name]) != np.asarray(theirs[name])
        failed = np.asarray(mine["failed"], bool) | np.asarray(mine["jackknifed"], bool)
        lengths_differ = np.asarray(mine["lengths"]) != np.asarray(theirs["lengths"])
        failure_time = lengths_differ & failed & ~changed
        changed |= lengths_differ & ~failed
        same = ~changed & ~failure_time
        a, b = np.asarray(mine["returns"]), np.asarray(theirs["returns"])
        scale = np.maximum(np.abs(a), 1.0)
        rel = np.abs(a - b)[same] / scale[same] if same.any() else np.zeros(1)
        rows.append(
            {
                "task_policy": key,
                "episodes": len(a),
                "outcomes_changed": int(changed.sum()),
                "failure_times_changed": int(failure_time.sum()),
                "safe_rate_delta": float(np.mean(mine["safe"]) - np.mean(theirs["safe"])),
                "success_rate_delta": float(np.mean(mine["success"]) - np.mean(theirs["success"])),
                "bitwise_equal_returns": int(np.sum(a == b)),
                "max_rel_return_diff": float(rel.max()),
            }
        )
    return rows


def _record_in_subprocess(
    target: str, tasks: Sequence[tuple[str, int]], episodes: int, folder: Path, cache: Path
) -> dict[str, Any]:
    out = folder / f"{target}.json"
    env = {**os.environ, **TARGETS[target], "NUMBA_CACHE_DIR": str(cache / target)}
    task_args = [f"{env_id}:{n}" for env_id, n in tasks]
    command = [sys.executable, "-m", "benchmarks.reproducibility", "record", "--out", str(out)]
    command += ["--episodes", str(episodes), "--tasks", *task_args]
    subprocess.run(command, env=env, check=True)
    return dict(json.loads(out.read_text()))


def _parse_task(text: str) -> tuple[str, int]:
    env_id, _, n = text.rpartition(":")
    if not env_id or not n.isdigit():
        raise argparse.ArgumentTypeError(f"a task is ENV_ID:N, got {text!r}")
    return env_id, int(n)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.reproducibility",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="command")
    run = sub.add_parser("run", help="every target in a subprocess, compared (the default)")
    run.add_argument("--quick", action="store_true", help="Reverse-v1 n = 2 only, 20 episodes")
    run.add_argument("--results", type=Path, default=RESULTS, help="CSV and Markdown folder")
    run.add_argument("--keep", type=Path, default=None, help="keep each target's JSON here")
    run.add_argument("--targets", nargs="+", choices=sorted(TARGETS), default=list(TARGETS))
    rec = sub.add_parser("record", help="this process's episodes to JSON")
    rec.add_argument("--out", type=Path, required=True)
    rec.add_argument("--episodes", type=int, default=100)
    rec.add_argument("--tasks", type=_parse_task, nargs="+", default=None)
    rec.add_argument("--policies", nargs="+", default=None)
    cmp = sub.add_parser("compare", help="compare two recorded JSON files")
    cmp.add_argument("reference", type=Path)
    cmp.add_argument("other", type=Path)
    return parser


def _markdown(rows: Sequence[dict[str, Any]], note: str) -> str:
    lines = [
        note,
        "",
        "| target | task, policy | outcomes changed (of episodes) | failures at another step"
        " | headline rate change | returns bit-equal | largest relative return difference |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        delta = row["safe_rate_delta"] if "Reverse" in row["task_policy"] else None
        if delta is None:
            delta = row["success_rate_delta"]
        lines.append(
            f"| {row['target']} | {row['task_policy']} | {row['outcomes_changed']} of "
            f"{row['episodes']} | {row['failure_times_changed']} | {100 * delta:+.0f} points "
            f"| {row['bitwise_equal_returns']} "
            f"| {row['max_rel_return_diff']:.1e} |"
        )
    return "\n".join(lines) + "\n"


def run_targets(args: argparse.Namespace) -> int:
    from agents.envs import HEADLINE_ENV_ID, HEADLINE_N_TRAILERS
    from trailer_env.benchmark import EPISODES, TASKS

    tasks = [(HEADLINE_ENV_ID, HEADLINE_N_TRAILERS)] if args.quick else list(TASKS)
    episodes = 20 if args.quick else EPISODES
    targets = [REFERENCE, *[t for t in args.targets if t != REFERENCE]]
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="repro-") as scratch:
        folder = args.keep or Path(scratch)
        folder.mkdir(parents=True, exist_ok=True)
        documents = {}
        for index, target in enumerate(targets, 1):
            print(
                f"[{index}/{len(targets)}] {target}: {len(tasks)} tasks x {episodes} episodes "
                f"({time.perf_counter() - started:.0f} s so far)",
                flush=True,
            )
            documents[target] = _record_in_subprocess(
                target, tasks, episodes, folder, Path(scratch) / "numba"
            )
    rows = []
    for target in targets[1:]:
        for row in compare(documents[REFERENCE], documents[target]):
            rows.append({"target": target, **row})
    changed = sum(row["outcomes_changed"] for row in rows)
    worst = max((row["max_rel_return_diff"] for row in rows), default=0.0)
    note = (
        f"{machine_note()}; reference {REFERENCE}; {len(tasks)} tasks x {episodes} episodes; "
        f"{changed} outcomes changed; largest relative return difference {worst:.1e}; "
        f"{time.perf_counter() - started:.0f} s"
    )
    print(note)
    csv_path = write_csv(args.results / "reproducibility.csv", rows)
    md_path = args.results / "reproducibility.md"
    partial = md_path.with_name(f".{md_path.name}.partial")
    partial.write_text(_markdown(rows, note))
    partial.replace(md_path)
    report_written(f"{csv_path} and {md_path}", started)
    return 0 if changed == 0 and worst <= RETURN_RTOL else 1


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command in (None, "run"):
        if args.command is None:
            args = parser.parse_args(["run", *(argv or [])])
        return run_targets(args)
    if args.command == "record":
        from trailer_env.benchmark import TASKS

        if args.episodes < 1:
            parser.error("--episodes must be >= 1")
        document = record(args.tasks or list(TASKS), args.episodes, args.policies)
        partial = args.out.with_name(f".{args.out.name}.partial")
        partial.write_text(json.dumps(document))
        partial.replace(args.out)
        return 0
    reference = json.loads(args.reference.read_text())
    rows = compare(reference, json.loads(args.other.read_text()))
    for row in rows:
        print(json.dumps(row))
    bad = sum(row["outcomes_changed"] for row in rows)
    worst = max((row["max_rel_return_diff"] for row in rows), default=0.0)
    print(f"{bad} outcomes changed; largest relative return difference {worst:.1e}")
    return 0 if bad == 0 and not math.isnan(worst) and worst <= RETURN_RTOL else 1


if __name__ == "__main__":
    raise SystemExit(main())
