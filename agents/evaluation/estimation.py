"""The estimating baseline under mismatched physics: its estimation error against time,
and its safe rate beside the LQR designed for nominal and for the true parameters (the
program: :mod:`agents.commands.estimation`).

For each n, one episode of the headline scene with ``randomize="mismatch20"`` is driven
by ``lqr-estimated`` (:mod:`agents.policies.estimator`), and after every step the
relative error of each parameter's estimate, ``|estimate / truth - 1|``, is kept. Then
``lqr``, ``lqr-adaptive`` (which reads the true parameters) and ``lqr-estimated`` are
scored on the same seeded episodes under the same draws. :func:`write_estimation` writes
``estimation.md`` (the rates and the error at chosen steps), ``estimation.json`` (every
figure) and ``estimation.png`` (the error against time, one panel per n), atomically.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import gymnasium as gym
import numpy as np

from agents.artifacts import files
from agents.envs import HEADLINE_ENV_ID, scene_title
from agents.evaluation.metrics import wilson_interval
from agents.evaluation.results import evaluate_policies
from agents.policies.baselines import make_baseline

#: The scene of the analysis: the headline scene, whose ``lqr-estimated`` baseline fits.
ENV_ID = HEADLINE_ENV_ID
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
    return {evaluation.label: evaluation.summary.safe_rate for evaluation in evaluations}


def markdown(
    counts: Sequence[int],
    found: dict[int, tuple[list[str], np.ndarray, dict[str, float]]],
    episodes: int,
    seed: int,
    error_seed: int,
) -> str:
    """The rates table, then the error table of each n."""
    lines = [
        f"{scene_title(ENV_ID)} with `randomize={RANDOMIZE}`, safe % on {episodes} episodes "
        f"from seed {seed} (95 % Wilson interval):",
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
    from agents.evaluation.plots import PAGE_DPI, PAGE_WIDTH_PX, _pyplot, save_page_figure

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
        axis.set_title(f"{scene_title(ENV_ID)}, n = {n}, {RANDOMIZE}", fontsize=10)
        axis.set_xlabel("step")
        axis.grid(alpha=0.3)
    axes[0][0].set_ylabel("|estimate / truth - 1| (%)")
    axes[0][-1].legend(fontsize=8)
    return save_page_figure(fig, plt, out)


def write_estimation(
    out: Path, counts: Sequence[int], episodes: int, seed: int, error_seed: int
) -> str:
    """Measure every n of ``counts`` (the error on the episode of ``error_seed``, the rates
    on ``episodes`` from ``seed``), write :data:`OUTPUTS` into ``out`` atomically and
    return the table."""
    found: dict[int, tuple[list[str], np.ndarray, dict[str, float]]] = {}
    for n in counts:
        names, errors = error_against_time(n, error_seed)
        found[n] = (names, errors, rates(n, episodes, seed))
    table = markdown(counts, found, episodes, seed, error_seed)
    document: dict[str, object] = {
        "env_id": ENV_ID,
        "randomize": RANDOMIZE,
        "episodes": episodes,
        "seed": seed,
        "error_seed": error_seed,
        "by_n": {
            str(n): {
                "rates": found[n][2],
                "parameters": found[n][0],
                "relative_error": found[n][1].tolist(),
            }
            for n in counts
        },
    }
    out.mkdir(parents=True, exist_ok=True)
    files.atomic_write_text(out / OUTPUTS[0], table)
    files.write_json(out / OUTPUTS[1], document)
    draw(found, out / OUTPUTS[2])
    return table
