"""The estimating baseline under mismatched physics: its estimation error against time,
and its safe rate beside the LQR designed for nominal and for the true parameters.

Usage::

    python -m agents.evaluation.estimation --n 1-3 --episodes 100 --out docs/generated/estimation

For each n, one episode of Reverse-v1 with ``randomize="mismatch20"`` (seed ``--seed``)
is driven by ``lqr-estimated`` (:mod:`agents.policies.estimator`), and after every step
the relative error of each parameter's estimate, ``|estimate / truth - 1|``, is kept.
Then ``lqr``, ``lqr-adaptive`` (which reads the true parameters) and ``lqr-estimated``
are scored on the same ``--episodes`` seeded episodes under the same draws (the test
seeds by default). Writes ``estimation.md`` (the rates and the error at chosen steps),
``estimation.json`` (every figure) and ``estimation.png`` (the error against time, one
panel per n) into ``--out``, atomically; existing files are replaced only with
``--overwrite``.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path

import gymnasium as gym
import numpy as np

from agents.artifacts import files
from agents.evaluation.across_n import check_out_options, parse_counts
from agents.evaluation.metrics import wilson_interval
from agents.evaluation.results import evaluate_policies
from agents.policies.baselines import make_baseline
from agents.progress import duration
from agents.seeds import TEST_SEED
from trailer_env.json_types import JSONObject

ENV_ID = "trailer_env/Reverse-v1"
RANDOMIZE = "mismatch20"
POLICIES = ("lqr", "lqr-adaptive", "lqr-estimated")
OUTPUTS = ("estimation.md", "estimation.json", "estimation.png")
#: The steps the table shows the error at (the chart shows every step).
SHOWN_STEPS = (0, 2, 3, 4, 6, 10, 50, 100, 399)


def error_against_time(n: int, seed: int, steps: int = 400) -> tuple[list[str], np.ndarray]:
    """The names of the estimated parameters and their relative errors (steps, P), one row
    per step of the episode of ``seed`` (shorter if it ends), before each action."""
    envs = gym.make_vec(
        ENV_ID,
        num_envs=1,
        vectorization_mode="vector_entry_point",
        n_trailers=n,
        randomize=RANDOMIZE,
    )
    observation, _ = envs.reset(seed=seed)
    native = envs.unwrapped
    policy = make_baseline("lqr-estimated", native.settings, ENV_ID)
    estimator = policy.estimator  # type: ignore[attr-defined]
    truth = native.core.param_values[0, estimator.columns].copy()
    errors = []
    for _ in range(steps):
        actions = policy(observation)
        errors.append(np.abs(estimator.values[0, estimator.columns] / truth - 1.0))
        observation, _, terminated, truncated, _ = envs.step(actions)
        if terminated[0] or truncated[0]:
            break
    envs.close()
    return list(estimator.names), np.array(errors)


def rates(n: int, episodes: int, seed: int) -> dict[str, float]:
    """Safe rate of each of :data:`POLICIES` on the same randomised episodes."""
    kwargs = {"n_trailers": n, "randomize": RANDOMIZE}
    evaluations = evaluate_policies(
        list(POLICIES), ENV_ID, kwargs, episodes, seed, with_seeds=False, progress=False
    )
    return {evaluation.label: float(evaluation.summary["safe_rate"]) for evaluation in evaluations}


def markdown(
    counts: Sequence[int],
    found: dict[int, tuple[list[str], np.ndarray, dict[str, float]]],
    episodes: int,
    seed: int,
    error_seed: int,
) -> str:
    """The rates table, then the error table of each n."""
    lines = [
        f"Reverse-v1 with `randomize={RANDOMIZE}`, safe % on {episodes} episodes from seed "
        f"{seed} (95 % Wilson interval):",
        "",
        "| n | " + " | ".join(POLICIES) + " |",
        "|---|" + "---|" * len(POLICIES),
    ]
    for n in counts:
        cells = []
        for name in POLICIES:
            rate = found[n][2][name]
            low, high = wilson_interval(round(rate * episodes), episodes)
            cells.append(f"{100 * rate:.0f} [{100 * low:.0f}, {100 * high:.0f}]")
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
    for n in counts:
        names, errors, _ = found[n]
        lines += [
            "",
            f"n = {n}, the episode of seed {error_seed}: `|estimate / truth - 1|` in % before "
            f"the action of each step ({len(errors)} steps)",
            "",
            "| step | " + " | ".join(names) + " |",
            "|---|" + "---|" * len(names),
        ]
        lines += [
            f"| {step} | " + " | ".join(f"{100 * value:.3g}" for value in errors[step]) + " |"
            for step in SHOWN_STEPS
            if step < len(errors)
        ]
    return "\n".join(lines) + "\n"


def draw(found: dict[int, tuple[list[str], np.ndarray, dict[str, float]]], out: Path) -> Path:
    """The error against time, one panel per n (log scale), written atomically."""
    from agents.evaluation.plots import PAGE_DPI, PAGE_WIDTH_PX, _pyplot

    plt = _pyplot()
    counts = sorted(found)
    fig, axes = plt.subplots(
        1,
        len(counts),
        figsize=(PAGE_WIDTH_PX / PAGE_DPI, 3.2),
        squeeze=False,
        sharey=True,
        layout="constrained",
    )
    for axis, n in zip(axes[0], counts, strict=True):
        names, errors, _ = found[n]
        for column, name in enumerate(names):
            axis.semilogy(np.maximum(100 * errors[:, column], 1e-6), label=name)
        axis.set_title(f"Reverse-v1, n = {n}, {RANDOMIZE}", fontsize=10)
        axis.set_xlabel("step")
        axis.grid(alpha=0.3)
    axes[0][0].set_ylabel("|estimate / truth - 1| (%)")
    axes[0][-1].legend(fontsize=8)
    with files.replacing(out) as temporary:
        fig.savefig(temporary, dpi=PAGE_DPI)
    plt.close(fig)
    return out


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog="python -m agents.evaluation.estimation",
        description=(__doc__ or "").split("\n")[0],
    )
    parser.add_argument("--n", type=parse_counts, default=parse_counts("1-3"), help="e.g. 1-3")
    parser.add_argument(
        "--episodes", type=int, default=100, help="episodes per policy and n (default 100)"
    )
    parser.add_argument("--seed", type=int, default=TEST_SEED, help="first episode's seed")
    parser.add_argument(
        "--error-seed", type=int, default=TEST_SEED, help="the episode whose error is drawn"
    )
    parser.add_argument("--out", type=Path, default=Path("out") / "estimation")
    parser.add_argument("--overwrite", action="store_true", help="replace an earlier run's files")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    check_out_options(parser, args, OUTPUTS, args.episodes)
    started = time.perf_counter()
    found: dict[int, tuple[list[str], np.ndarray, dict[str, float]]] = {}
    for n in args.n:
        names, errors = error_against_time(n, args.error_seed)
        found[n] = (names, errors, rates(n, args.episodes, args.seed))
    table = markdown(args.n, found, args.episodes, args.seed, args.error_seed)
    document: JSONObject = {
        "env_id": ENV_ID,
        "randomize": RANDOMIZE,
        "episodes": args.episodes,
        "seed": args.seed,
        "error_seed": args.error_seed,
        "by_n": {
            str(n): {
                "rates": found[n][2],
                "parameters": found[n][0],
                "relative_error": found[n][1].tolist(),
            }
            for n in args.n
        },
    }
    args.out.mkdir(parents=True, exist_ok=True)
    files.atomic_write_text(args.out / OUTPUTS[0], table)
    files.write_json(args.out / OUTPUTS[1], document)
    draw(found, args.out / OUTPUTS[2])
    print(table, end="")
    print(f"wrote {args.out} in {duration(time.perf_counter() - started)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
