"""The results tables as the site shows them: short headers and cells, the training
spelled out under the table, the legend once, the headline scenario first."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from agents.artifacts.cards import ModelCard
from agents.artifacts.results import Summary
from agents.evaluation.metrics import EpisodeResults, summary_of
from agents.evaluation.report import (
    HEADLINE,
    SCENARIOS,
    report_order,
    scenario_section,
    tables_document,
)
from agents.evaluation.results import Evaluation
from agents.evaluation.tables import (
    TRAINING_KINDS,
    markdown_table,
    scenario_legend,
    scenario_table,
    table_header,
    table_legend,
    training_footnote,
    training_kind,
    training_label,
    training_note,
)

DAGGER_CARD = {
    "algo": "ppo",
    "recipe": "dagger",
    "seed": 1,
    "timesteps": 614_400,
    "selected_at_iteration": 3,
    "wall_time_s": 500,
}
PPO_CARD = {"algo": "ppo", "seed": 0, "timesteps": 2_000_000, "selected_at_timesteps": 1_500_000}


def _results() -> EpisodeResults:
    """Four episodes: two safe, one folded, one that entered the band (10 % of its steps)."""
    return EpisodeResults(
        seeds=np.arange(4),
        returns=np.array([100.0, 200.0, 300.0, 400.0]),
        lengths=np.array([400, 400, 120, 400]),
        jackknifed=np.array([False, False, True, False]),
        success=np.array([True, True, False, True]),
        failed=np.array([False, False, True, False]),
        band_steps=np.array([0, 0, 0, 40]),
        min_margin=np.array([1.0, 1.0, 0.2, 0.25]),
        actuator_work=np.zeros(4),
        margins=np.ones(4),
    )


def card(document: dict[str, object]) -> ModelCard:
    return ModelCard.from_json(document)


def _evaluations() -> list[Evaluation]:
    summary = summary_of(_results())
    spread: list[tuple[int | None, Summary]] = [
        (seed, summary.replace(safe_rate=rate)) for seed, rate in ((0, 0.4), (1, 0.5), (2, 0.6))
    ]
    return [
        Evaluation("lqr", "lqr", ModelCard(), _results()),
        Evaluation("mpc", "mpc", ModelCard(), _results()),
        Evaluation("dagger_x", "dagger_x.zip", card(DAGGER_CARD), _results(), None, spread),
    ]


def test_training_labels_are_short_and_the_notes_go_under_the_table() -> None:
    assert training_label(card(DAGGER_CARD)) == "DAgger, 0.614M labels"
    assert training_label(card(PPO_CARD)) == "PPO, 2M steps"
    assert training_label(card({"algo": "sac", "timesteps": 90_000})) == "SAC, 90k steps"
    assert training_label(card({}), "mpc") == "oracle"
    assert training_label(card({}), "mpc-replay") == "oracle"
    assert training_label(card({}), "lqr") == "-"
    assert training_footnote(_evaluations()) == (
        "training: **mpc**: oracle (exact model and state), 768k simulated steps per "
        "episode; **dagger_x**: PPO policy by DAgger from mpc, seed 1, 0.614M labels "
        "(kept iteration 3), 500 s"
    )
    assert training_footnote(_evaluations()[:1]) == ""
    distilled = {
        "algo": "ppo",
        "recipe": "dagger",
        "expert": "specialists",
        "planner": {"policy": "1-3=ppo_reverse_v1_n{n},dagger_reverse_v1_n{n}"},
        "seed": 0,
        "timesteps": 614_400,
        "selected_at_iteration": 5,
        "wall_time_s": 1812.8,
    }
    assert training_note(card(distilled)) == (
        "PPO policy by DAgger from specialists 1-3=ppo_reverse_v1_n{n},dagger_reverse_v1_n{n}, "
        "seed 0, 0.614M labels (kept iteration 5), 1813 s"
    )


def test_training_labels_name_the_exploration_and_the_shaping() -> None:
    gsde = {**PPO_CARD, "hyperparams": {"use_sde": True, "sde_sample_freq": 4}}
    assert training_label(card(gsde)) == "PPO (gSDE), 2M steps"
    assert training_note(card(gsde)).startswith("PPO (gSDE), seed ")
    shaped = {**gsde, "shaping": {"potential": "lqr"}}
    assert training_label(card(shaped)) == "PPO (gSDE) + lqr shaping, 2M steps"
    sac_sde = {
        "algo": "sac",
        "timesteps": 90_000,
        "hyperparams": {"policy_kwargs": {"use_sde": True}},
    }
    assert training_label(card(sac_sde)) == "SAC (gSDE), 90k steps"
    assert training_label(card({**PPO_CARD, "hyperparams": {"use_sde": False}})) == "PPO, 2M steps"
    wide = {"use_sde": True, "policy_kwargs": {"net_arch": [256, 256]}}
    assert (
        training_label(card({**PPO_CARD, "hyperparams": wide})) == "PPO (gSDE, 256x256), 2M steps"
    )
    narrow = {"policy_kwargs": {"net_arch": [64, 64], "log_std_init": -1.0}}
    assert training_label(card({**PPO_CARD, "hyperparams": narrow})) == "PPO, 2M steps"
    assert training_label(
        card({**PPO_CARD, "hyperparams": {"policy_kwargs": {"net_arch": [32]}}})
    ) == ("PPO (32), 2M steps")
    randomised = {**PPO_CARD, "hyperparams": wide, "env_kwargs": {"randomize": "mismatch20"}}
    assert training_label(card(randomised)) == "PPO (gSDE, 256x256, mismatch20), 2M steps"
    by_row = {"n_trailers": [1, 3], "trailer_draw": "row", "randomize": {"M": [0.8, 1.2]}}
    assert training_label(card({**PPO_CARD, "env_kwargs": by_row})) == (
        "PPO (randomised, n by row), 2M steps"
    )
    plain = {"n_trailers": [1, 3], "trailer_draw": "episode"}
    assert training_label(card({**PPO_CARD, "env_kwargs": plain})) == "PPO, 2M steps"


def test_markdown_table_rows_and_footnote() -> None:
    evaluations = _evaluations()
    table = markdown_table(evaluations)
    lines = table.splitlines()
    assert lines[0] == (
        "| policy | training | return | safe % [95% CI] | fold % | band % | min margin "
        "| success % | stop % | safe % over seeds |"
    )
    assert lines[1] == "|---|---|---|---|---|---|---|---|---|---|"
    # Returns 100-400: mean 250, sd 111.8 (joined by no-break spaces); safe 2 of 4 (Wilson
    # 15-85 %); one fold.
    assert lines[2] == (
        "| lqr | - | 250.0\u00a0±\u00a0111.8 | 50 [15, 85] | 25 | 2.5 | 0.61 / 0.20 | 75 | 0 | - |"
    )
    assert lines[3].startswith("| mpc | oracle | 250.0\u00a0±\u00a0111.8 |")
    assert lines[4] == (
        "| dagger_x | DAgger, 0.614M labels | 250.0\u00a0±\u00a0111.8 | 50 [15, 85] | 25 | 2.5 "
        "| 0.61 / 0.20 | 75 | 0 | 50 ± 8 (40-60, 3 seeds) |"
    )
    assert lines[5] == ""
    assert lines[6] == training_footnote(evaluations)
    assert len(lines) == 7
    # Ten cells in every row, as in the header.
    assert all(line.count("|") == 11 for line in lines[:5])
    # Baselines alone: no footnote line.
    assert markdown_table(evaluations[:1]) == table_header() + lines[2] + "\n"
    assert table_header("success_rate").splitlines()[0].endswith("| success % over seeds |")


def test_section_heading_names_the_scenario_only_and_the_legend_comes_once() -> None:
    fresh = _evaluations()[:1] + _evaluations()[2:]  # no fresh row for the oracle
    section = scenario_section(
        "trailer_env/Reverse-v1", 2, _evaluations(), 4, fresh=fresh, picture="img/x.png"
    )
    lines = section.splitlines()
    assert lines[0] == "#### Reverse-v1, n = 2"
    assert lines[2] == "![Reverse-v1, n = 2: every policy's rate on the test starts](img/x.png)"
    assert lines[4] == (
        "`trailer_env/Reverse-v1`, test: 4 episodes, seeds 1000..1003; fresh: seeds 7000..7003"
    )
    assert lines[6].startswith("| policy | made by | safe % test [95% CI] | safe % fresh")
    assert lines[-1].startswith("ceiling: ")
    headings = [line for line in section.splitlines() if line.startswith("#")]
    assert headings == ["#### Reverse-v1, n = 2"]
    document = tables_document(
        [section, section.replace("n = 2", "n = 3")], ["trailer_env/Reverse-v1"] * 2
    )
    assert document.startswith(
        scenario_legend(["trailer_env/Reverse-v1"]) + "\n\n#### Reverse-v1, n = 2\n"
    )
    assert document.count("Columns:") == 1
    assert document.count("#### ") == 2


def test_scenario_table_rates_gap_and_rebuild_command() -> None:
    """Two of the four episodes are safe (50 %, Wilson [15, 85]); against a ceiling of
    0.75 the gap is 25 points; the oracle has no fresh row; the model's command rebuilds it."""
    evaluations = _evaluations()
    table = scenario_table(evaluations, [evaluations[0], evaluations[2]], 0.75)
    rows = table.splitlines()
    assert rows[2] == "| lqr | baseline | 50.0 [15, 85] | 50.0 [15, 85] | 25.0 | 25 | - | - |"
    assert rows[3] == "| mpc | oracle | 50.0 [15, 85] | - | 25.0 | 25 | - | - |"
    assert rows[4] == (
        "| dagger_x | imitation | 50.0 [15, 85] | 50.0 [15, 85] | 25.0 | 25 "
        "| 50 ± 8 (40-60, 3 seeds) | 8.3 min |"
    )
    assert "rebuild: `python -m agents.reproduce dagger_x --out out/reproduce/dagger_x`" in table
    assert "| - |" in scenario_table(evaluations, None, None).splitlines()[2]


def test_training_kinds() -> None:
    assert [training_kind(card({}), "zero"), training_kind(card({}), "ilqr")] == [
        "baseline",
        "oracle",
    ]
    assert training_kind(card(DAGGER_CARD)) == "imitation"
    assert training_kind(card(PPO_CARD)) == "from reward"
    assert training_kind(card({"algo": "ppo_lag"})) == "constrained"
    assert set(TRAINING_KINDS) == {"baseline", "oracle", "imitation", "from reward", "constrained"}


def test_the_headline_scenario_comes_first() -> None:
    scenarios = [
        ("trailer_env/Reverse-v0", 1),
        ("trailer_env/Reverse-v1", 1),
        ("trailer_env/Reverse-v1", 2),
        ("trailer_env/Coast-v0", 1),
        ("trailer_env/Reverse-v1", 3),
    ]
    assert HEADLINE == ("trailer_env/Reverse-v1", 2)
    assert report_order(scenarios) == [
        ("trailer_env/Reverse-v1", 2),
        ("trailer_env/Reverse-v1", 1),
        ("trailer_env/Reverse-v1", 3),
        ("trailer_env/Reverse-v0", 1),
        ("trailer_env/Coast-v0", 1),
    ]


def _stop_and_headline(legend: str) -> tuple[str, str]:
    stop = legend.split("**stop %** failures without a fold (", 1)[1].split("); **", 1)[0]
    headline = legend.split("the scene's headline rate (", 1)[1].split(") of each", 1)[0]
    return stop, headline


def test_the_legend_words_each_scene_from_its_core() -> None:
    """ "stop %" and "% over seeds" are spelled out per scene from the cores'
    ``failure_words`` and ``headline_metric``, not as Reverse's for every scene."""
    assert _stop_and_headline(table_legend(["trailer_env/Reverse-v1"])) == (
        "Reverse-v1: the convoy slowed to 0.3 m/s",
        "safe on Reverse-v1",
    )
    assert _stop_and_headline(table_legend(["trailer_env/Heading-v0"])) == (
        "none on Heading-v0",
        "success on Heading-v0",
    )
    every = [
        "trailer_env/Reverse-v0",
        "trailer_env/Dock-v0",
        "trailer_env/Coast-v0",
        "trailer_env/Reverse-v0",
        "trailer_env/Heading-v0",
    ]
    assert _stop_and_headline(table_legend(every)) == (
        "Reverse-v0: the convoy stopped reversing; Dock-v0: a miss (the last axle ran past "
        "the dock); none on Coast-v0, Heading-v0",
        "safe on Reverse-v0; success on Dock-v0, Coast-v0, Heading-v0",
    )
    with pytest.raises(ValueError, match="got none"):
        table_legend([])
    with pytest.raises(ValueError, match="unknown environment 'trailer_env/Nope-v0'"):
        table_legend(["trailer_env/Nope-v0"])


def test_the_committed_results_page_has_the_report_legend() -> None:
    page = Path(__file__).resolve().parents[3] / "docs" / "generated" / "results_tables.md"
    first = page.read_text().splitlines()[0]
    assert first == scenario_legend([env_id for env_id, _ in SCENARIOS])


def test_the_tables_of_a_count_hold_the_models_trained_over_a_range_that_holds_it() -> None:
    from agents.artifacts.shipped import models_covering

    at_four = [path.stem for path in models_covering("trailer_env/Reverse-v1", 4)]
    assert at_four[0] == "dagger_reverse_v1_n4"  # the count's own models first
    assert {"distill_reverse_v1_sequence16", "dagger_reverse_v1_sequence16m"} <= set(at_four)
    assert "distill_reverse_v1_sequence" not in at_four  # trained on n = 1-3
    at_two = [path.stem for path in models_covering("trailer_env/Reverse-v1", 2)]
    assert {"ppo_reverse_v1_n2", "distill_reverse_v1_sequence"} <= set(at_two)
    assert "dagger_reverse_v1_general" not in at_two  # randomised physics: not this scenario
