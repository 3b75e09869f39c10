"""Time to the ceiling: per scenario, how far the best learned agent stands from the certified
ceiling, and the wall time it took to make it.

Read from the report's results documents (:class:`~agents.artifacts.results.ResultsDocument`,
``results.json`` of ``python -m agents.report``): the ceiling is the committed
certificate's share of the test starts (:func:`agents.evaluation.ceiling.ceiling_fraction`),
the agent is the committed model with the highest headline rate on those starts, and the
time is the ``wall_time_s`` its run recorded on its card: for an imitation agent the
whole ``agents.imitate`` run (the planner's labels, the training and the choice of the
iteration kept), for reinforcement learning the whole ``agents.train`` run (training and
its validation evaluations). Beside it, the best agent learned from the scene's reward
alone (a card with neither an imitation ``recipe`` nor a fine-tuning start, ``init_from``),
with its rate and time, so that imitation
and reinforcement learning stand side by side. Choosing among training seeds is not in
it. Beside each wall time, the speed of the machine that ran it, as its card records it
(:class:`~agents.artifacts.cards.HostSpeed`: a short fixed benchmark measured when the run
started, with the load then); cards written before that record show ``-`` there.

``python -m agents.time_to_ceiling RESULTS_JSON`` prints the table
(:mod:`agents.commands.time_to_ceiling`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from agents.artifacts.cards import HostSpeed
from agents.artifacts.results import PolicyResult, ResultsDocument, TrainingFacts
from agents.envs import headline_metric, scene_title
from agents.evaluation.ceiling import ceiling_fraction

#: The targets of the table's two last columns: points below the ceiling, minutes of wall time.
GAP_TARGET_POINTS = 2.0
TIME_TARGET_MINUTES = 15.0


#: The line under the table's heading in the results tables.
TIME_TO_CEILING_LEGEND = (
    "Per scenario, the committed learned agent with the highest headline rate on these "
    "test episodes against the certified ceiling, and the wall time its run recorded on its "
    "card (imitation: labels, training and selection of the iteration; reinforcement "
    "learning: training with its validation evaluations) with, in brackets, the speed of "
    "the machine that ran it (`python -m agents.host_speed`'s benchmark when the run "
    "started: environment steps per second, one PPO update, the load; the time alone where "
    "the card predates that record); whether it stands within 2 points of the ceiling and "
    "its run within 15 minutes; and beside it the best agent learned from the reward alone "
    "(no imitation). `python -m agents.time_to_ceiling results.json` "
    "prints it from a report's results."
)


@dataclass(frozen=True)
class CeilingGap:
    """One scenario's best learned agent against its ceiling (rates in [0, 1])."""

    env_id: str
    n_trailers: int
    ceiling: float | None
    agent: str | None
    rate: float | None
    seeds_mean: float | None
    seeds: int
    wall_minutes: float | None
    host: HostSpeed | None = None
    reward_agent: str | None = None
    reward_rate: float | None = None
    reward_minutes: float | None = None
    reward_host: HostSpeed | None = None

    @property
    def gap_points(self) -> float | None:
        """Ceiling minus the agent's rate, in percentage points (None without either)."""
        if self.ceiling is None or self.rate is None:
            return None
        return 100.0 * (self.ceiling - self.rate)


def _from_reward(training: TrainingFacts) -> bool:
    """Whether a policy was learned from the scene's reward alone: not imitated, and not
    fine-tuned from an imitated (or any other) model."""
    return training.recipe is None and training.init_from is None


def gap_of(document: ResultsDocument) -> CeilingGap:
    """The :class:`CeilingGap` of one results document.

    Raises:
        ValueError: If the document's ``n_trailers`` is not one count.
    """
    env_id, n = document.env_id, document.n_trailers
    if not isinstance(n, int):
        raise ValueError(f"the time to the ceiling needs one count of trailers, got {n!r}")
    metric = headline_metric(env_id)
    learned = document.by_kind("model")
    ceiling = ceiling_fraction(env_id, n, document.episodes, document.seeds[0])
    if not learned:
        return CeilingGap(env_id, n, ceiling, None, None, None, 0, None)
    best = max(learned, key=lambda policy: policy.summary.rate(metric))
    seeds = best.training_seeds or ()
    seeds_mean = sum(row.summary.rate(metric) for row in seeds) / len(seeds) if seeds else None
    from_reward = [policy for policy in learned if _from_reward(policy.training)]
    reward = max(from_reward, key=lambda policy: policy.summary.rate(metric), default=None)
    return CeilingGap(
        env_id,
        n,
        ceiling,
        best.name,
        best.summary.rate(metric),
        seeds_mean,
        len(seeds),
        _wall_minutes(best),
        best.training.host,
        None if reward is None else reward.name,
        None if reward is None else reward.summary.rate(metric),
        None if reward is None else _wall_minutes(reward),
        None if reward is None else reward.training.host,
    )


def _wall_minutes(policy: PolicyResult) -> float | None:
    wall = policy.training.wall_time_s
    return None if wall is None else wall / 60.0


def _wall(minutes: float | None, host: HostSpeed | None) -> str:
    """A run's wall time with the speed of the machine that ran it (``-`` without a wall
    time; the time alone where the card predates the host record)."""
    if minutes is None:
        return "-"
    return f"{minutes:.1f} min" if host is None else f"{minutes:.1f} min ({host.cell()})"


def _percent(value: float | None) -> str:
    return "-" if value is None else f"{100 * value:.0f} %"


def _verdict(value: float | None, target: float) -> str:
    if value is None:
        return "-"
    # Compared as shown (a 98 % agent under a 100 % ceiling is 2 points, not 2.0000000000000018).
    return "yes" if round(value, 6) <= target else "no"


def time_to_ceiling_table(documents: Sequence[ResultsDocument]) -> str:
    """The Markdown table: one row per document, in their order."""
    lines = [
        "| scene, n | ceiling (certified) | best learned agent | its rate (gap, points) "
        "| mean over training seeds | wall time of its run (its machine) | within "
        f"{GAP_TARGET_POINTS:g} points / {TIME_TARGET_MINUTES:g} min "
        "| best from reward alone | its rate | its wall time (its machine) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for document in documents:
        row = gap_of(document)
        gap = row.gap_points
        rate = _percent(row.rate) if gap is None else f"{_percent(row.rate)} ({gap:.0f})"
        seeds = "-" if row.seeds_mean is None else f"{_percent(row.seeds_mean)} ({row.seeds})"
        verdicts = (
            f"{_verdict(gap, GAP_TARGET_POINTS)} / "
            f"{_verdict(row.wall_minutes, TIME_TARGET_MINUTES)}"
        )
        lines.append(
            f"| {scene_title(row.env_id)}, {row.n_trailers} | {_percent(row.ceiling)} "
            f"| {row.agent or '-'} | {rate} | {seeds} | {_wall(row.wall_minutes, row.host)} "
            f"| {verdicts} | {row.reward_agent or '-'} | {_percent(row.reward_rate)} "
            f"| {_wall(row.reward_minutes, row.reward_host)} |"
        )
    return "\n".join(lines) + "\n"
