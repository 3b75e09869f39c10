"""The Markdown comparison table and its notes (training, oracle, spread over seeds).

The table is sized for the site's content column (938 px on the results page at 1280
px): short headers, :func:`table_legend` saying once what they mean, and a short
training label in the cell (:func:`training_label`), the whole description in a
footnote line under the table (:func:`training_footnote`).
"""

from __future__ import annotations

from collections.abc import Sequence

from agents.algorithms.recipes import recipe_name
from agents.artifacts.cards import ModelCard
from agents.artifacts.results import Summary
from agents.envs import ENV_IDS, core_class_of, scene_title
from agents.evaluation.metrics import wilson_interval
from agents.evaluation.results import Evaluation
from agents.policies.baselines import BASELINES

#: No-break space: a return such as "394.8 ± 31.4" stays on one line of its cell.
NBSP = "\u00a0"


def oracle_note(label: str, episode_steps: int = 400) -> str:
    """What the training footnote says of a baseline: its record's ``oracle_note``
    (:data:`agents.policies.baselines.BASELINES`), "-" unless an oracle."""
    baseline = BASELINES.get(label)
    if baseline is None or baseline.oracle_note is None:
        return "-"
    return baseline.oracle_note(episode_steps)


def _steps_text(steps: float) -> str:
    return f"{steps / 1e6:.3g}M" if steps >= 100_000 else f"{steps / 1e3:.3g}k"


#: The recipe of the models imitated by DAgger (``agents.imitate``).
DAGGER = "dagger"


def _steps(card: ModelCard) -> int:
    """The steps (labels, for imitation) the run took: its ``timesteps``, else its budget."""
    if card.timesteps is not None:
        return card.timesteps
    return card.budget or 0


def training_note(card: ModelCard, label: str = "") -> str:
    """ "PPO, seed 0, 2.0M steps, 95 s" from a model card (a baseline: :func:`oracle_note`)."""
    if card.empty:
        return oracle_note(label)
    steps = _steps(card)
    selected = card.selected_at_timesteps
    chosen = f" (kept {_steps_text(selected)})" if selected not in (None, steps) else ""
    wall = card.wall_time_s
    wall_text = f", {wall:.0f} s" if wall is not None else ""
    algo = (card.algo or "?").upper()
    if card.recipe == DAGGER:
        iteration = card.selected_at_iteration
        kept = f" (kept iteration {iteration})" if iteration is not None else ""
        expert = card.expert or "mpc"
        expert_policies = None if card.planner is None else card.planner.policy
        if expert_policies is not None:  # distilled: the expert policies' specs say which
            expert = f"{expert} {expert_policies}"
        return (
            f"{algo} policy by DAgger from {expert}, "
            f"seed {card.seed}, {_steps_text(steps)} labels{kept}{wall_text}"
        )
    recipe = recipe_name(card.to_json(), upper=True)
    return f"{recipe}, seed {card.seed}, {_steps_text(steps)} steps{chosen}{wall_text}"


def training_label(card: ModelCard, label: str = "") -> str:
    """The table cell's short form of :func:`training_note`: "DAgger, 0.614M labels",
    "PPO, 2M steps", "oracle" for an oracle baseline, "-" for the other baselines."""
    if card.empty:
        return "oracle" if oracle_note(label) != "-" else "-"
    steps = _steps_text(_steps(card))
    if card.recipe == DAGGER:
        return f"DAgger, {steps} labels"
    return f"{recipe_name(card.to_json(), upper=True)}, {steps} steps"


def training_footnote(evaluations: Sequence[Evaluation]) -> str:
    """The line under a table that spells out each training label: "training: **mpc**:
    oracle (exact model and state), ...; **dagger_reverse_v1_n2**: PPO policy by DAgger
    from mpc, seed 0, ...", or "" when no row has one (baselines only)."""
    notes = [
        f"**{evaluation.label}**: {note}"
        for evaluation in evaluations
        if (note := training_note(evaluation.card, evaluation.label)) != "-"
    ]
    return f"training: {'; '.join(notes)}" if notes else ""


def seeds_note(evaluation: Evaluation, metric: str = "safe_rate") -> str:
    """ "96 ± 2 (94-98, 3 seeds)": ``metric`` in % over the training seeds, or "-"."""
    spread = evaluation.seed_spread(metric)
    if spread is None:
        return "-"
    mean, sd, low, high = (100 * value for value in spread)
    count = len(evaluation.seed_summaries or [])
    return f"{mean:.0f} ± {sd:.0f} ({low:.0f}-{high:.0f}, {count} seeds)"


def _metric_name(metric: str) -> str:
    return metric.removesuffix("_rate")


def table_header(metric: str = "safe_rate") -> str:
    """The header row and rule of :func:`markdown_table` (ten columns)."""
    return (
        "| policy | training | return | safe % [95% CI] | fold % | band % "
        f"| min margin | success % | stop % | {_metric_name(metric)} % over seeds |\n"
        "|---|---|---|---|---|---|---|---|---|---|\n"
    )


def _scenes_text(env_ids: Sequence[str]) -> tuple[str, str]:
    """What "stop %" and "% over seeds" mean on the scenes ``env_ids``, from each scene's
    core (``failure_words``, ``headline_metric``): "Reverse-v1: the convoy slowed to 0.3
    m/s; none on Heading-v0" and "safe on Reverse-v1; success on Heading-v0"."""
    failures, without = [], []
    metrics: dict[str, list[str]] = {}
    for env_id in dict.fromkeys(env_ids):
        core, title = core_class_of(env_id), scene_title(env_id)
        if core.failure_words:
            failures.append(f"{title}: {core.failure_words}")
        else:
            without.append(title)
        metrics.setdefault(_metric_name(core.headline_metric), []).append(title)
    if without:
        failures.append(f"none on {', '.join(without)}")
    headline = "; ".join(f"{metric} on {', '.join(titles)}" for metric, titles in metrics.items())
    return "; ".join(failures), headline


def table_legend(env_ids: Sequence[str] = ENV_IDS) -> str:
    """What the columns of :func:`markdown_table` hold, in one paragraph (written once
    per page of tables; the metrics are defined in docs/agents.md, Metrics).

    ``env_ids`` are the scenes the page's tables show: "stop %" and "% over seeds" are
    spelled out for each from its core's ``failure_words`` and ``headline_metric``.

    Raises:
        ValueError: If ``env_ids`` is empty or names an unregistered id.
    """
    if not env_ids:
        raise ValueError("table_legend needs the scenes the tables show, got none")
    failures, headline = _scenes_text(env_ids)
    return (
        "Columns: **return** mean ± sd; **safe %** safe episodes with their 95 % Wilson "
        "interval; **fold %** episodes ended by a jackknife; **band %** share of the steps "
        "in the singular band; **min margin** the episode's smallest singular margin, "
        "mean / worst over the episodes; **success %** the env's `is_success`; **stop %** "
        f"failures without a fold ({failures}); "
        f"**% over seeds** the scene's headline rate ({headline}) of each "
        "training seed's model on the same episodes, mean ± sd (min-max, seeds); "
        "**training** is short for the line under the table."
    )


def markdown_table(evaluations: Sequence[Evaluation], metric: str = "safe_rate") -> str:
    """The comparison table in Markdown (rates in %, margins in [0, 1]) followed, after
    a blank line, by :func:`training_footnote` when there is one.

    The last column gives ``metric`` (the scene's headline rate) over a committed
    model's training seeds. "stop %" counts the failures that are not folds (the
    scene's ``failure_words``). :func:`table_legend` explains the headers.
    """
    lines = []
    for evaluation in evaluations:
        s = evaluation.summary
        low, high = s.safe_rate_ci
        lines.append(
            f"| {evaluation.label} | {training_label(evaluation.card, evaluation.label)} "
            f"| {s.mean_return:.1f}{NBSP}±{NBSP}{s.std_return:.1f} "
            f"| {100 * s.safe_rate:.0f} [{100 * low:.0f}, {100 * high:.0f}] "
            f"| {100 * s.jackknife_rate:.0f} | {100 * s.band_time_fraction:.1f} "
            f"| {s.min_margin_mean:.2f} / {s.min_margin_worst:.2f} "
            f"| {100 * s.success_rate:.0f} | {100 * s.stop_rate:.0f} "
            f"| {seeds_note(evaluation, metric)} |"
        )
    footnote = training_footnote(evaluations)
    table = table_header(metric) + "\n".join(lines) + "\n"
    return table + (f"\n{footnote}\n" if footnote else "")


#: How a policy of the results tables was made, in the order the tables explain them.
TRAINING_KINDS = ("baseline", "oracle", "imitation", "from reward", "constrained")


def training_kind(card: ModelCard, label: str = "") -> str:
    """One of :data:`TRAINING_KINDS`: "oracle" for a baseline reading the exact state,
    "imitation" for DAgger (from a planner or from trained specialists), "constrained" for
    a cost-constrained algorithm (PPO-Lagrangian), "from reward" for the other learners."""
    if card.empty:
        return "oracle" if oracle_note(label) != "-" else "baseline"
    if card.recipe == DAGGER:
        return "imitation"
    return "constrained" if card.algo == "ppo_lag" else "from reward"


def _rate_cell(summary: Summary, metric: str) -> str:
    """ "99.0 [95, 100]": the rate in % with its 95 % Wilson interval."""
    episodes = summary.episodes
    rate = summary.rate(metric)
    low, high = wilson_interval(round(rate * episodes), episodes)
    return f"{100 * rate:.1f} [{100 * low:.0f}, {100 * high:.0f}]"


def _wall_cell(card: ModelCard) -> str:
    wall = card.wall_time_s
    return f"{wall / 60:.1f} min" if wall is not None else "-"


def reproduce_command(label: str) -> str:
    """The command that rebuilds the committed model ``label`` from its card."""
    return f"python -m agents.reproduce {label} --out out/reproduce/{label}"


def scenario_table(
    test: Sequence[Evaluation],
    fresh: Sequence[Evaluation] | None,
    ceiling: float | None,
    metric: str = "safe_rate",
) -> str:
    """One scenario's results table (Markdown), then the lines under it: how each learned
    row was trained (:func:`training_footnote`) and the command that rebuilds it.

    Columns: the policy; how it was made (:func:`training_kind`); the headline rate in %
    with its 95 % Wilson interval on the test starts and on fresh ones (``fresh``: the same
    policies in the same order on other seeds; "-" where a policy has no fresh row, such as
    the replay of the certificate's records, which exist on the test starts only); the gap
    in points to the certified ``ceiling`` on the test starts (negative where a policy
    passes it); the share of episodes ended by a fold; the headline rate over the committed
    model's training seeds; the wall time its card records.
    """
    by_label = {evaluation.label: evaluation for evaluation in fresh or ()}
    word = _metric_name(metric)
    lines = [
        f"| policy | made by | {word} % test [95% CI] | {word} % fresh [95% CI] "
        "| gap | fold % | over seeds | training |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for evaluation in test:
        summary = evaluation.summary
        other = by_label.get(evaluation.label)
        gap = "-" if ceiling is None else f"{100 * (ceiling - summary.rate(metric)):.1f}"
        lines.append(
            f"| {evaluation.label} | {training_kind(evaluation.card, evaluation.label)} "
            f"| {_rate_cell(summary, metric)} "
            f"| {'-' if other is None else _rate_cell(other.summary, metric)} "
            f"| {gap} | {100 * summary.jackknife_rate:.0f} "
            f"| {seeds_note(evaluation, metric)} | {_wall_cell(evaluation.card)} |"
        )
    notes = [training_footnote(test)]
    commands = [
        f"`{reproduce_command(evaluation.label)}`"
        for evaluation in test
        if not evaluation.card.empty
    ]
    if commands:
        notes.append(f"rebuild: {'; '.join(commands)}")
    return "\n".join(lines) + "\n\n" + "\n\n".join(note for note in notes if note) + "\n"


def scenario_legend(env_ids: Sequence[str] = ENV_IDS) -> str:
    """What the columns of :func:`scenario_table` hold, in one paragraph (once per page).

    Raises:
        ValueError: If ``env_ids`` is empty or names an unregistered id.
    """
    if not env_ids:
        raise ValueError("scenario_legend needs the scenes the tables show, got none")
    _, headline = _scenes_text(env_ids)
    return (
        f"Columns: the scene's headline rate ({headline}) in % with its 95 % Wilson interval, "
        "on the test starts and on fresh ones; **made by**: "
        f"{', '.join(TRAINING_KINDS)}; **gap**: points under the certified ceiling on the test "
        "starts (negative: over a ceiling that is a lower bound); **fold %**: episodes ended "
        "by a jackknife; **over seeds**: the headline rate of each training seed's model on "
        "the test starts, mean ± sd (min-max, seeds); **training**: the wall time the run "
        "recorded on its card. Under each table: how each row was trained and the command "
        "that rebuilds it."
    )
