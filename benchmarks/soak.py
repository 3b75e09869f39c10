"""Soak test: many random steps across scenes, trailer counts and action modes.

Run with ``python -m benchmarks.soak [--steps N] [--quick]``.

Every combination of the four scenes, ``n`` in {0, 1, 2, 3, 8} and the action modes
servo, accel and planar (60 cases) runs its share of ``--steps`` environment steps
(default 10^6 in all) through the native vector environment (``--num-envs``
environments per case, default 64, one kernel call per step). Actions are uniform
in [-1, 1], except that one row in ten gets +-1e3 (out of range: the environment
clips it). Counted per case: observations, rewards and info values that are not
finite, exceptions (the case resets and goes on), episodes ended by a fold, the
largest substep count the fidelity chose, and the wall time.

A run writes under ``--results``/``--images`` (default ``out/benchmarks/``); the
committed outputs: a table on stdout and ``benchmarks/results/soak.csv`` (one row per case).
"""

from __future__ import annotations

import time
import warnings
from collections import Counter
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import trailer_env
from benchmarks._common import RESULTS, machine_note, write_csv

NS = (0, 1, 2, 3, 8)
MODES = ("servo", "accel", "planar")
#: Fraction of action rows replaced by an out-of-range value (+-OUT_OF_RANGE).
OUT_OF_RANGE_FRACTION = 0.1
OUT_OF_RANGE = 1e3


def soak_case(
    scene: str, n: int, mode: str, steps: int, num_envs: int, seed: int
) -> dict[str, Any]:
    """Run ``steps`` environment steps (rounded up to whole vector steps) of one case.

    ``scene`` is a registered id, e.g. "trailer_env/Reverse-v0".
    """
    envs = gym.make_vec(
        scene,
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        n_trailers=n,
        action_mode=mode,
    )
    core = envs.unwrapped.core
    rng = np.random.default_rng(seed)
    envs.reset(seed=seed)
    counts: Counter[str] = Counter()
    errors: Counter[str] = Counter()
    max_substeps = 0
    shape = (num_envs, envs.unwrapped.settings.action_dim)
    start = time.perf_counter()
    vector_steps = -(-steps // num_envs)
    for _ in range(vector_steps):
        actions = rng.uniform(-1.0, 1.0, shape)
        wild = rng.random(num_envs) < OUT_OF_RANGE_FRACTION
        actions[wild] = OUT_OF_RANGE * rng.choice([-1.0, 1.0], (int(wild.sum()), shape[1]))
        try:
            obs, reward, terminated, truncated, info = envs.step(actions)
        except Exception as error:  # counted, never hidden: the soak's whole point
            errors[type(error).__name__] += 1
            envs.reset()
            continue
        counts["nonfinite_obs"] += int(np.count_nonzero(~np.isfinite(obs).all(axis=1)))
        counts["nonfinite_reward"] += int(np.count_nonzero(~np.isfinite(reward)))
        for key, value in info.items():
            if not key.startswith("_"):
                values = np.asarray(value, dtype=np.float64)
                counts["nonfinite_info"] += int(np.count_nonzero(~np.isfinite(values)))
        counts["folds"] += int(np.count_nonzero(info["jackknifed"] & terminated))
        counts["episodes"] += int(np.count_nonzero(terminated | truncated))
        max_substeps = max(max_substeps, int(core.substeps.max()))
    envs.close()
    return {
        "scene": scene.removeprefix("trailer_env/").removesuffix("-v0"),
        "n": n,
        "mode": mode,
        "num_envs": num_envs,
        "env_steps": vector_steps * num_envs,
        "nonfinite_obs": counts["nonfinite_obs"],
        "nonfinite_reward": counts["nonfinite_reward"],
        "nonfinite_info": counts["nonfinite_info"],
        "exceptions": sum(errors.values()),
        "exception_types": " ".join(f"{name}:{k}" for name, k in sorted(errors.items())),
        "episodes": counts["episodes"],
        "folds": counts["folds"],
        "max_substeps": max_substeps,
        "seconds": round(time.perf_counter() - start, 3),
    }


def main(argv: list[str] | None = None) -> int:
    """Run the soak and write its CSV; returns 1 if anything was not finite or raised."""
    import argparse

    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.soak",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--steps", type=int, default=10**6, help="environment steps in all")
    parser.add_argument("--quick", action="store_true", help="10^4 steps in all")
    parser.add_argument("--num-envs", type=int, default=64, help="environments per case")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--results", type=Path, default=RESULTS, help="CSV folder")
    args = parser.parse_args(argv)
    total = 10**4 if args.quick else args.steps
    if total < 1 or args.num_envs < 1:
        parser.error("--steps and --num-envs must be >= 1")
    cases = [(env_id, n, mode) for env_id in trailer_env.ENVIRONMENTS for n in NS for mode in MODES]
    per_case = -(-total // len(cases))
    rows = []
    start = time.perf_counter()
    print(
        f"{'scene':8} {'n':>2} {'mode':6} {'steps':>8} {'!obs':>5} {'!rew':>5} "
        f"{'!info':>5} {'exc':>4} {'folds':>6} {'max k':>5} {'s':>6}"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for index, (scene, n, mode) in enumerate(cases):
            row = soak_case(scene, n, mode, per_case, args.num_envs, args.seed + index)
            rows.append(row)
            print(
                f"{row['scene']:8} {n:>2} {mode:6} {row['env_steps']:>8} "
                f"{row['nonfinite_obs']:>5} "
                f"{row['nonfinite_reward']:>5} {row['nonfinite_info']:>5} "
                f"{row['exceptions']:>4} {row['folds']:>6} {row['max_substeps']:>5} "
                f"{row['seconds']:>6.2f}"
            )
    steps = sum(row["env_steps"] for row in rows)
    bad = {
        key: sum(row[key] for row in rows)
        for key in ("nonfinite_obs", "nonfinite_reward", "nonfinite_info", "exceptions")
    }
    elapsed = time.perf_counter() - start
    print(
        f"total: {steps} env steps in {len(cases)} cases, {elapsed:.0f} s "
        f"({steps / elapsed / 1e3:.0f} k steps/s, {machine_note()}); non-finite observations "
        f"{bad['nonfinite_obs']}, rewards {bad['nonfinite_reward']}, info values "
        f"{bad['nonfinite_info']}; exceptions {bad['exceptions']}; "
        f"folds {sum(row['folds'] for row in rows)}"
    )
    path = write_csv(args.results / "soak.csv", rows)
    print(f"wrote {path}")
    return 1 if any(bad.values()) else 0


if __name__ == "__main__":
    raise SystemExit(main())
