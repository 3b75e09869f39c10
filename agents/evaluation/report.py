"""The scenarios of the results pages and the actuator-authority sweep."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from agents.artifacts.cards import read_model_card
from agents.artifacts.shipped import MODELS_DIR
from agents.envs import ENV_IDS, HEADLINE_ENV_ID, HEADLINE_N_TRAILERS, scene_title
from agents.evaluation.ceiling import ceiling_fraction, ceiling_note
from agents.evaluation.pictures import baseline_levels, learning_curve
from agents.evaluation.results import (
    Evaluation,
    curve_metric,
    evaluate_policies,
)
from agents.evaluation.tables import scenario_legend, scenario_table
from agents.progress import plural
from agents.seeds import FRESH_SEED, TEST_SEED

#: The recipe of the models imitated by DAgger (``agents.imitate``).
DAGGER = "dagger"


def committed_scenarios(directory: Path = MODELS_DIR) -> tuple[tuple[str, int], ...]:
    """(environment id, number of trailers) of every committed model's card, in the scene
    table's order, then by n: the scenarios the README reports."""
    found = set()
    for path in directory.glob("*.zip"):
        card = read_model_card(path)
        env_id, n = card.env_id, card.n_trailers
        if env_id in ENV_IDS and isinstance(n, int):
            found.add((env_id, n))
    return tuple(sorted(found, key=lambda scenario: (ENV_IDS.index(scenario[0]), scenario[1])))


#: (environment id, number of trailers) of the README's results.
SCENARIOS: tuple[tuple[str, int], ...] = committed_scenarios()


#: The scenario whose margins and frames are drawn, and whose table comes first.
HEADLINE = (HEADLINE_ENV_ID, HEADLINE_N_TRAILERS)


def report_order(scenarios: Sequence[tuple[str, int]]) -> list[tuple[str, int]]:
    """``scenarios`` in the order of the results page: the headline scenario, the rest
    of its scene, then the other scenes in the given order."""
    return sorted(
        scenarios, key=lambda scenario: (scenario[0] != HEADLINE[0], scenario != HEADLINE)
    )


def scenario_slug(env_id: str, n: int) -> str:
    """ "reverse_v1_n2": the file name of a scenario's picture."""
    return f"{scene_title(env_id).lower().replace('-', '_')}_n{n}"


def scenario_section(
    env_id: str,
    n: int,
    evaluations: Sequence[Evaluation],
    episodes: int,
    seed: int = TEST_SEED,
    *,
    fresh: Sequence[Evaluation] | None = None,
    fresh_seed: int = FRESH_SEED,
    picture: str | None = None,
) -> str:
    """One scenario's part of the results page: a heading that names the scenario only
    (the page's table of contents lists the headings), its picture (``picture``, a path
    relative to the page), the episodes, the table (:func:`scenario_table`: the test starts,
    ``fresh`` on the episodes from ``fresh_seed``, the gap to the ceiling, how to rebuild
    each model) and the ceiling line (:func:`agents.evaluation.ceiling.ceiling_note`)."""
    title = f"{scene_title(env_id)}, n = {n}"
    where = f"`{env_id}`, test: {plural(episodes, 'episode')}, seeds {seed}..{seed + episodes - 1}"
    if fresh is not None:
        where += f"; fresh: seeds {fresh_seed}..{fresh_seed + episodes - 1}"
    ceiling = ceiling_fraction(env_id, n, episodes, seed)
    table = scenario_table(evaluations, fresh, ceiling, curve_metric(env_id))
    image = f"![{title}: every policy's rate on the test starts]({picture})\n\n" if picture else ""
    note = ceiling_note(env_id, n, episodes, seed)
    return f"#### {title}\n\n{image}{where}\n\n{table}\n{note}\n"


def tables_document(sections: Sequence[str], env_ids: Sequence[str]) -> str:
    """The results tables' Markdown: what the columns mean on the scenes ``env_ids``
    (:func:`scenario_legend`, once), then the sections."""
    return "\n".join([f"{scenario_legend(env_ids)}\n", *sections])


#: Actuator settings of the authority sweep (ConvoyParams / EnvSettings overrides).
AUTHORITY_SWEEP: tuple[dict[str, float], ...] = (
    {},
    {"s_max": 1.0},
    {"rail_accel_max": 8.0},
    {"s_max": 1.0, "rail_accel_max": 8.0},
    {"mu": 1.0},
)


def authority_table(episodes: int, seed: int = TEST_SEED) -> str:
    """The LQR baseline's safe rate on Reverse-v0 as the actuator gets stronger (Markdown).

    Defaults: mass mu = 0.5, stroke s_max = 0.5 m, acceleration bound 4 m/s^2.
    """
    env_id = "trailer_env/Reverse-v0"
    lines = [
        "| actuator (changes from the defaults) | n = 2 safe | n = 3 safe |",
        "|---|---|---|",
    ]
    for changes in AUTHORITY_SWEEP:
        rates = []
        for n in (2, 3):
            env_kwargs = {"n_trailers": n, **changes}
            (evaluation,) = evaluate_policies(["lqr"], env_id, env_kwargs, episodes, seed)
            rates.append(f"{100 * evaluation.summary.safe_rate:.0f}%")
        name = ", ".join(f"{key} = {value:g}" for key, value in changes.items()) or "defaults"
        lines.append(f"| {name} | {rates[0]} | {rates[1]} |")
    return "\n".join(lines) + "\n"


#: One panel of the learning-curve grid: its title, the models' curves by name, the
#: baselines' levels and the metric (:func:`agents.evaluation.plots.plot_curve_grid`).
CurvePanel = tuple[str, dict[str, Path], dict[str, float], str]


def curve_panel(env_id: str, n: int, evaluations: list[Evaluation]) -> CurvePanel:
    """One panel of the learning-curve grid: the models' curves and the baselines' levels."""
    metric = curve_metric(env_id)
    curves = {}
    for evaluation in evaluations:
        curve = learning_curve(evaluation)
        if not evaluation.card.empty and curve is not None:
            name = (evaluation.card.algo or evaluation.label).upper()
            if evaluation.card.recipe == DAGGER:
                name = "DAgger (PPO policy)"
            curves[name] = curve
    levels = baseline_levels(evaluations, metric)
    return f"{scene_title(env_id)}, n = {n}", curves, levels, metric
