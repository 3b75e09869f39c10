"""Where one SB3 PPO iteration's wall time goes on Reverse-v1 (n = 2), committed hyperparameters.

Run with ``python -m benchmarks.ppo_profile [--quick] [--iterations K]`` (needs the
``agents`` extra; from a clone's root).

PPO is built as ``agents.train`` builds it (``agents/hyperparams/ppo.yml``: the native
batch through :class:`trailer_env.sb3.ConvoySB3VecEnv`, ``VecNormalize``, the
hyperparameter file's network) and learns K iterations of ``n_steps x n_envs`` steps
each (one rollout and one update), after one warm-up iteration. Timers wrapped around
the methods split the wall time into:

* **env: physics step**: the batched core's compiled step (``ConvoyCore.step``);
* **env: resets**: drawing the starts of the episodes that ended (``reset_rows_from``);
* **adapter**: the rest of ``ConvoySB3VecEnv.step_wait`` (infos, episode statistics,
  copies);
* **policy forward**: the policy's forward passes while collecting the rollout;
* **update**: ``PPO.train`` (the epochs of minibatch gradient steps);
* **SB3 rollout, other**: what remains of ``learn`` (rollout buffer, ``VecNormalize``,
  callbacks, logging).

torch and numba run on one thread each, as the project trains on a shared machine.
A run writes ``ppo_profile.csv`` under ``--results`` (default ``out/benchmarks/results``)
and prints the table.
"""

from __future__ import annotations

import functools
import time
from collections import defaultdict
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from agents.envs import HEADLINE_ENV_ID
from benchmarks._common import machine_note, one_thread, parse_command, report_written, write_csv

ENV_ID = HEADLINE_ENV_ID
N_TRAILERS = 2


@contextmanager
def timed(owner: Any, name: str, totals: dict[str, float], label: str) -> Iterator[None]:
    """Add the wall time of every call of ``owner.name`` to ``totals[label]`` in the block."""
    original = getattr(owner, name)

    @functools.wraps(original)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        started = time.perf_counter()
        try:
            return original(*args, **kwargs)
        finally:
            totals[label] += time.perf_counter() - started

    setattr(owner, name, wrapper)
    try:
        yield
    finally:
        setattr(owner, name, original)


def build_model() -> Any:
    """PPO on the native batch as ``agents.train`` builds it (committed hyperparameters)."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.envs import make_sb3_env
    from agents.training.config import load_hyperparams

    hp = load_hyperparams("ppo", ENV_ID)
    venv: Any = make_sb3_env(ENV_ID, hp.n_envs, {**hp.env_kwargs, "n_trailers": N_TRAILERS}, 0)
    if hp.normalize is not None:
        venv = VecNormalize(venv, **{"gamma": hp.algo_kwargs.get("gamma", 0.99), **hp.normalize})
    return PPO(hp.policy, venv, seed=0, device="cpu", verbose=0, **hp.algo_kwargs)


def profile(iterations: int) -> dict[str, float]:
    """Seconds per category over ``iterations`` PPO iterations (after one warm-up)."""
    import torch
    from stable_baselines3 import PPO

    from trailer_env.sb3 import ConvoySB3VecEnv

    torch.set_num_threads(1)
    model = build_model()
    batch = model.n_steps * model.n_envs
    model.learn(batch)  # warm-up: compiles the kernels, fills caches
    adapter = model.get_env()
    while not isinstance(adapter, ConvoySB3VecEnv):
        adapter = adapter.venv
    core_class = type(adapter.core)
    totals: dict[str, float] = defaultdict(float)
    policy = model.policy
    with (
        timed(core_class, "step", totals, "env: physics step"),
        timed(core_class, "reset_rows_from", totals, "env: resets"),
        timed(ConvoySB3VecEnv, "step_wait", totals, "adapter (with env)"),
        timed(policy, "forward", totals, "policy forward"),
        timed(PPO, "train", totals, "update"),
    ):
        started = time.perf_counter()
        model.learn(iterations * batch, reset_num_timesteps=False)
        totals["learn"] = time.perf_counter() - started
    totals["adapter"] = (
        totals.pop("adapter (with env)") - totals["env: physics step"] - totals["env: resets"]
    )
    accounted = sum(
        totals[key] for key in ("env: physics step", "env: resets", "adapter", "policy forward")
    )
    totals["SB3 rollout, other"] = totals["learn"] - totals["update"] - accounted
    totals["steps"] = float(iterations * batch)
    return dict(totals)


CATEGORIES: tuple[str, ...] = (
    "env: physics step",
    "env: resets",
    "adapter",
    "policy forward",
    "SB3 rollout, other",
    "update",
)


def table(totals: dict[str, float]) -> str:
    """The Markdown table: seconds, share of the wall time, microseconds per env step."""
    lines = [
        "| part | seconds | share | us per env step |",
        "|---|---|---|---|",
    ]
    for key in CATEGORIES:
        seconds = totals[key]
        lines.append(
            f"| {key} | {seconds:.2f} | {100 * seconds / totals['learn']:.1f}% "
            f"| {1e6 * seconds / totals['steps']:.2f} |"
        )
    lines.append(
        f"| **all of learn** | {totals['learn']:.2f} | 100% | "
        f"{1e6 * totals['learn'] / totals['steps']:.2f} |"
    )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    args = parse_command(
        "python -m benchmarks.ppo_profile", __doc__, "one iteration instead of three", argv
    )
    start = time.perf_counter()
    with one_thread():
        totals = profile(1 if args.quick else 3)
    print(f"{ENV_ID}, n = {N_TRAILERS}, {int(totals['steps'])} steps ({machine_note()})")
    print(table(totals))
    row: dict[str, Any] = {key: totals[key] for key in (*CATEGORIES, "learn", "steps")}
    write_csv(args.results / "ppo_profile.csv", [row])
    report_written(f"{args.results}/ppo_profile.csv", start)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
