"""iLQR with exact Jacobians against finite differences: the goal scenes' certify search.

Run with ``python -m benchmarks.ilqr_jacobians [--quick]``.

The search ``agents.certify`` runs for a goal scene (:func:`agents.certification.search.
goal_search`: iLQR on every start in one batch, then up to two restarts with a longer
horizon and more iterations on the starts that missed the goal), once with the step's
Jacobians by forward differences of the kernel (``ILQRConfig(jacobians="differences")``,
the default) and once exact (``"exact"``: forward-mode autograd through the
differentiable twin, :mod:`agents.oracles.ilqr_tangent`), on the certificates' starts
(test seeds 1000-1099) of Dock-v0 and Coast-v0 with one and two trailers. Witnesses are
not run: the table counts what the planner alone reaches. Both modes run in the same
process, one after the other per scene, numba and torch on one thread each. Written:
``ilqr_jacobians.csv`` (one row per scene, n and mode) and ``ilqr_jacobians.md`` (the
table) under ``--results``. ``--quick``: Coast-v0, n = 1, 10 starts, no restart.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

from benchmarks._common import machine_note, one_thread, parse_command, write_csv

#: (env id, n) of the full run.
SCENES = (
    ("trailer_env/Coast-v0", 1),
    ("trailer_env/Coast-v0", 2),
    ("trailer_env/Dock-v0", 1),
    ("trailer_env/Dock-v0", 2),
)
SEEDS = list(range(1000, 1100))
RESTARTS = 2
MODES = ("differences", "exact")


def search(env_id: str, n: int, mode: str, seeds: list[int], restarts: int) -> dict[str, Any]:
    """One goal search; its row of the table."""
    from agents.certification.search import goal_search
    from agents.oracles.ilqr import ILQRConfig
    from trailer_env.registry import core_class_of
    from trailer_env.settings import settings_from_kwargs

    settings = settings_from_kwargs(n_trailers=n)
    found = goal_search(
        core_class_of(env_id), settings, seeds, ILQRConfig(jacobians=mode), restarts
    )
    part = found.planner
    return {
        "env_id": env_id,
        "n_trailers": n,
        "jacobians": mode,
        "starts": len(seeds),
        "first_pass_success": part.first_pass_safe,
        "first_pass_wall_time_s": part.first_pass_wall_time_s,
        "success": int(found.reached.sum()),
        "open": int((~found.reached).sum()),
        "wall_time_s": part.wall_time_s,
        "simulated_steps_per_episode": round(part.simulated_steps_per_episode),
    }


def table(rows: list[dict[str, Any]], note: str) -> str:
    """The markdown table: per scene and n, both modes side by side."""
    lines = [
        "| scene | n | Jacobians | goal, 1st pass | 1st pass, s | goal, all | open | all, s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        scene = row["env_id"].split("/")[-1]
        lines.append(
            f"| {scene} | {row['n_trailers']} | {row['jacobians']} | "
            f"{row['first_pass_success']}/{row['starts']} | {row['first_pass_wall_time_s']} | "
            f"{row['success']}/{row['starts']} | {row['open']} | {row['wall_time_s']} |"
        )
    return "\n".join(lines) + f"\n\n{note}\n"


def main(argv: list[str] | None = None) -> None:
    """Run the searches, print and write the table."""
    args = parse_command(
        "python -m benchmarks.ilqr_jacobians",
        __doc__,
        "Coast-v0, n = 1, 10 starts, no restart",
        argv,
    )
    import torch

    torch.set_num_threads(1)
    scenes = SCENES[:1] if args.quick else SCENES
    seeds = SEEDS[:10] if args.quick else SEEDS
    restarts = 0 if args.quick else RESTARTS
    started = time.perf_counter()
    rows = []
    with one_thread():
        for env_id, n in scenes:
            for mode in MODES:
                row = search(env_id, n, mode, seeds, restarts)
                print(row, flush=True)
                rows.append(row)
    load = ", ".join(f"{value:.1f}" for value in os.getloadavg())
    note = (
        f"Seeds {seeds[0]}-{seeds[-1]}, up to {restarts} restarts, one thread each for numba "
        f"and torch, {machine_note()}, load average at the end {load}; "
        "`python -m benchmarks.ilqr_jacobians` wrote it."
    )
    results: Path = args.results
    write_csv(results / "ilqr_jacobians.csv", rows)
    text = table(rows, note)
    partial = results / ".ilqr_jacobians.md.partial"
    partial.write_text(text)
    partial.replace(results / "ilqr_jacobians.md")
    print(text)
    print(f"wrote {results}/ilqr_jacobians.csv and .md in {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
