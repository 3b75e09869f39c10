"""The Markdown comparison table and its notes (training, oracle, spread over seeds)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from agents.evaluation.results import Evaluation


def oracle_note(label: str, episode_steps: int = 400) -> str:
    """What the table says in the training column of a baseline ("-" unless an oracle)."""
    if label == "mpc-replay":
        return "oracle: the certified planner's committed records, replayed open-loop"
    if label == "ilqr":
        return "oracle: exact model and state, deterministic iLQR (agents.oracles.ilqr)"
    if label != "mpc":
        return "-"
    from agents.oracles.planner import PlannerConfig

    per_episode = PlannerConfig().steps_per_decision * episode_steps
    return f"oracle: exact model and state, {per_episode / 1000:.0f}k simulated steps per episode"


def training_note(card: dict[str, Any], label: str = "") -> str:
    """ "PPO, seed 0, 2.0M steps, 95 s" from a model card ("-" for baselines)."""
    if not card:
        return oracle_note(label)

    def steps_text(steps: float) -> str:
        return f"{steps / 1e6:.3g}M" if steps >= 100_000 else f"{steps / 1e3:.3g}k"

    steps = card.get("timesteps", card.get("budget", 0))
    selected = card.get("selected_at_timesteps")
    chosen = f" (kept {steps_text(selected)})" if selected not in (None, steps) else ""
    wall = card.get("wall_time_s")
    wall_text = f", {wall:.0f} s" if isinstance(wall, (int, float)) else ""
    algo = str(card.get("algo", "?")).upper()
    if card.get("recipe") == "dagger":
        iteration = card.get("selected_at_iteration")
        kept = f" (kept iteration {iteration})" if iteration is not None else ""
        return (
            f"{algo} policy by DAgger from {card.get('expert', 'mpc')}, seed {card.get('seed')}, "
            f"{steps_text(steps)} labels{kept}{wall_text}"
        )
    return f"{algo}, seed {card.get('seed')}, {steps_text(steps)} steps{chosen}{wall_text}"


def seeds_note(evaluation: Evaluation, metric: str = "safe_rate") -> str:
    """ "96 ± 2% (94-98, 3 seeds)": ``metric`` over the training seeds, or "-"."""
    spread = evaluation.seed_spread(metric)
    if spread is None:
        return "-"
    mean, sd, low, high = (100 * value for value in spread)
    count = len(evaluation.seed_summaries or [])
    return f"{mean:.0f} ± {sd:.0f}% ({low:.0f}-{high:.0f}, {count} seeds)"


def markdown_table(evaluations: Sequence[Evaluation], metric: str = "safe_rate") -> str:
    """The comparison table in Markdown (rates in %, margins in [0, 1]).

    The last column gives ``metric`` (the scene's headline rate) over a committed
    model's training seeds.

    "stopped reversing" counts the failures that are not folds: on Reverse-v0 the
    episodes ended because the cart's speed reached u >= 0 (other scenes have none).
    """
    header = (
        "| policy | training | return (mean ± sd) | safe episodes [95% CI] | jackknife "
        "| time in band | min margin (mean / worst) | success | stopped reversing "
        f"| {metric.removesuffix('_rate')} over training seeds |\n"
        "|---|---|---|---|---|---|---|---|---|---|\n"
    )
    lines = []
    for evaluation in evaluations:
        s = evaluation.summary
        stopped = s["failure_rate"] - s["jackknife_rate"]
        low, high = s["safe_rate_ci"]
        lines.append(
            f"| {evaluation.label} | {training_note(evaluation.card, evaluation.label)} "
            f"| {s['mean_return']:.1f} ± {s['std_return']:.1f} "
            f"| {100 * s['safe_rate']:.0f}% [{100 * low:.0f}, {100 * high:.0f}] "
            f"| {100 * s['jackknife_rate']:.0f}% | {100 * s['band_time_fraction']:.1f}% "
            f"| {s['min_margin_mean']:.2f} / {s['min_margin_worst']:.2f} "
            f"| {100 * s['success_rate']:.0f}% | {100 * stopped:.0f}% "
            f"| {seeds_note(evaluation, metric)} |"
        )
    return header + "\n".join(lines) + "\n"
