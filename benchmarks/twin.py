"""The differentiable twin's step against the compiled kernel's, per control step.

Run with ``python -m benchmarks.twin [--quick]``.

One control step of Reverse-v1 for a batch of 256 environments with 3 trailers (the
defaults: servo actuator, auto substeps), from the starts of ``reset(seed=0..255)``
and one random action per row, timed three ways in the same process: the kernel's step
(:meth:`trailer_env.core.ConvoyCore.step`, one compiled call), the twin's forward step
(:func:`trailer_env.twin.step` under ``torch.no_grad``, float64) and its forward plus
backward (the gradient of the rewards and the next states' sum with respect to the
state and the action). Every case starts from the same state each call, so each does
the same work. Wall time, the best of three interleaved passes, numba and torch on one
thread each; with a GPU the twin is timed on it too (synchronised). Printed: seconds per
step and the ratio to the kernel's step; written: ``twin.csv`` under ``--results``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from agents.envs import HEADLINE_ENV_ID
from benchmarks._common import (
    best_of_rounds,
    machine_note,
    one_thread,
    parse_command,
    report_written,
    write_csv,
)

BATCH = 256
N_TRAILERS = 3
ENV_ID = HEADLINE_ENV_ID


def cases(batch: int, n: int) -> dict[str, Callable[[], Any]]:
    """Name -> a closure taking one control step of ``batch`` rows (the same work each call)."""
    import torch

    from trailer_env.registry import core_class_of
    from trailer_env.settings import settings_from_kwargs
    from trailer_env.twin import TwinParams, TwinState, step

    core = core_class_of(ENV_ID)(settings_from_kwargs(n_trailers=n), batch)
    rows = np.arange(batch, dtype=np.int64)
    core.reset_rows(rows, [np.random.default_rng(seed) for seed in range(batch)])
    z0, act0 = core.z.copy(), core.act.copy()
    action = np.random.default_rng(1).uniform(-1.0, 1.0, (batch, 1))
    params = TwinParams.from_core(core)

    def kernel() -> None:
        core.z[:] = z0
        core.act[:] = act0
        core.step(action)

    def twin(device: str) -> tuple[Callable[[], Any], Callable[[], Any]]:
        state = TwinState.from_core(core, device=device)
        torch_action = torch.tensor(action, device=device)
        sync = torch.cuda.synchronize if device == "cuda" else (lambda: None)

        def forward() -> None:
            with torch.no_grad():
                step(state, torch_action, params)
            sync()

        def backward() -> None:
            z = state.z.clone().requires_grad_(True)
            pushed = torch_action.clone().requires_grad_(True)
            after, reward, _, _ = step(state._replace(z=z), pushed, params)
            (reward.sum() + after.z.sum()).backward()
            sync()

        return forward, backward

    runs: dict[str, Callable[[], Any]] = {"kernel step": kernel}
    devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    for device in devices:
        forward, backward = twin(device)
        runs[f"twin forward ({device})"] = forward
        runs[f"twin forward+backward ({device})"] = backward
    return runs


def measure(quick: bool) -> list[dict[str, Any]]:
    """Seconds per step of every case and its ratio to the kernel's step."""
    import torch

    torch.set_num_threads(1)
    runs = cases(BATCH, N_TRAILERS)
    with one_thread():
        seconds = best_of_rounds(
            list(runs.values()),
            rounds=1 if quick else 3,
            min_total=0.05 if quick else 0.5,
            clock=time.perf_counter,
        )
    kernel = seconds[0]
    return [
        {
            "case": name,
            "batch": BATCH,
            "n_trailers": N_TRAILERS,
            "seconds_per_step": value,
            "ratio_to_kernel": value / kernel,
        }
        for name, value in zip(runs, seconds, strict=True)
    ]


def main(argv: list[str] | None = None) -> None:
    """Run the benchmark, print its rows and write twin.csv."""
    args = parse_command("python -m benchmarks.twin", __doc__, "one short pass per case", argv)
    start = time.perf_counter()
    rows = measure(args.quick)
    print(f"Reverse-v1, n = {N_TRAILERS}, batch {BATCH}, one thread ({machine_note()})")
    for row in rows:
        print(
            f"  {row['case']:<32} {row['seconds_per_step'] * 1e3:9.3f} ms/step"
            f"  x{row['ratio_to_kernel']:8.1f}"
        )
    path = write_csv(args.results / "twin.csv", rows)
    report_written(str(path), start)


if __name__ == "__main__":
    main()
