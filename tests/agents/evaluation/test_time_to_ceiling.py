"""The time-to-ceiling table: the best learned agent against the committed certificate."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from agents.artifacts.results import ResultsDocument, Summary
from agents.commands.time_to_ceiling import main
from agents.evaluation.time_to_ceiling import gap_of, time_to_ceiling_table


def _summary(rate: float) -> dict:
    """A summary whose safe and success rates are ``rate`` (the other fields at 0)."""
    fields = dict.fromkeys(f.name for f in dataclasses.fields(Summary))
    return {
        **{name: 0.0 for name in fields},
        "episodes": 100,
        "safe_rate_ci": [0.0, 1.0],
        "safe_rate": rate,
        "success_rate": rate,
    }


def _document(env_id: str, n: int, policies: list[dict]) -> ResultsDocument:
    return ResultsDocument.from_json(_raw(env_id, n, policies), "test")


def _raw(env_id: str, n: int, policies: list[dict]) -> dict:
    return {
        "env_id": env_id,
        "env_kwargs": {"n_trailers": n},
        "episodes": 100,
        "seeds": [1000, 1099],
        "policies": policies,
    }


def _model(
    name: str, rate: float, wall: float, seeds: list[float] = (), recipe: str | None = None
) -> dict:
    return {
        "name": name,
        "kind": "model",
        "training": {"wall_time_s": wall, **({"recipe": recipe} if recipe else {})},
        **_summary(rate),
        "training_seeds": [{"seed": k, **_summary(r)} for k, r in enumerate(seeds)],
    }


def test_the_best_model_is_set_against_the_committed_ceiling(tmp_path: Path, capsys) -> None:
    document = _document(
        "trailer_env/Reverse-v1",
        3,
        [
            {"name": "lqr", "kind": "baseline", **_summary(0.99)},
            _model("slow", 0.91, 1500.0, [0.91, 0.93, 0.89]),
            _model("fast", 0.98, 600.0),
        ],
    )
    row = gap_of(document)
    # The committed Reverse-v1 n = 3 certificate solves all the test starts 1000-1099.
    assert row.ceiling == pytest.approx(1.0)
    assert row.agent == "fast" and row.rate == 0.98  # baselines are not agents
    assert row.gap_points == pytest.approx(2.0) and row.wall_minutes == pytest.approx(10.0)
    assert row.seeds == 0 and row.seeds_mean is None
    table = time_to_ceiling_table([document])
    assert "| Reverse-v1, 3 | 100 % | fast | 98 % (2) | - | 10.0 min | yes / yes |" in table
    assert table.rstrip().endswith("| fast | 98 % | 10.0 min |")
    slow = gap_of(
        _document("trailer_env/Reverse-v1", 3, [_model("slow", 0.91, 1500.0, [0.91, 0.93, 0.89])])
    )
    assert slow.seeds == 3 and slow.seeds_mean == pytest.approx(0.91)
    assert "| 91 % (9) | 91 % (3) | 25.0 min | no / no | slow | 91 % |" in time_to_ceiling_table(
        [_document("trailer_env/Reverse-v1", 3, [_model("slow", 0.91, 1500.0, [0.91, 0.93, 0.89])])]
    )
    at_target = _document("trailer_env/Reverse-v1", 1, [_model("edge", 0.98, 60.0)])
    assert "| 98 % (2) | - | 1.0 min | yes / yes | edge | 98 % |" in time_to_ceiling_table(
        [at_target]
    )
    path = tmp_path / "results.json"
    path.write_text(json.dumps([document.to_json()]))
    assert main([str(path)]) == 0
    assert capsys.readouterr().out == table


def test_the_best_agent_from_reward_alone_stands_beside_imitation() -> None:
    document = _document(
        "trailer_env/Reverse-v1",
        3,
        [
            _model("dagger", 0.91, 1500.0, recipe="dagger"),
            _model("ppo_shaped", 0.76, 1800.0),
            _model("ppo_plain", 0.05, 900.0),
        ],
    )
    row = gap_of(document)
    assert (row.agent, row.reward_agent) == ("dagger", "ppo_shaped")
    assert row.reward_rate == 0.76 and row.reward_minutes == pytest.approx(30.0)
    assert "| no / no | ppo_shaped | 76 % | 30.0 min |" in time_to_ceiling_table([document])
    dagger = _model("d", 0.9, 60.0, recipe="dagger")
    only_imitation = _document("trailer_env/Reverse-v1", 3, [dagger])
    assert gap_of(only_imitation).reward_agent is None
    tuned = _model("ppo_from_dagger", 0.95, 600.0)
    tuned["training"]["init_from"] = "agents/models/dagger_reverse_v1_n3.zip"
    with_tuned = _document("trailer_env/Reverse-v1", 3, [dagger, tuned])
    assert (gap_of(with_tuned).agent, gap_of(with_tuned).reward_agent) == ("ppo_from_dagger", None)
    assert time_to_ceiling_table([only_imitation]).rstrip().endswith("| no / yes | - | - | - |")


def test_a_scenario_without_agents_or_certificate_shows_dashes(tmp_path: Path, capsys) -> None:
    # Heading-v0 has no certificate; no model was evaluated.
    document = _document("trailer_env/Heading-v0", 2, [])
    dashes = "| Heading-v0, 2 |" + " - |" * 5 + " - / - |" + " - |" * 3
    assert dashes in time_to_ceiling_table([document])
    path = tmp_path / "broken.json"
    path.write_text('[{"env_id": "trailer_env/Heading-v0"}]')
    with pytest.raises(SystemExit) as refused:
        main([str(path)])
    assert refused.value.code == 2 and "is not a report's results.json" in capsys.readouterr().err


def test_each_wall_time_stands_beside_the_speed_of_the_host_that_ran_it() -> None:
    host = {
        "benchmark": "reverse_v1_n3_batch8_ppo2048",
        "env_steps_per_s": 231_531.8,
        "ppo_update_s": 0.8067,
        "cpus": 2,
        "torch_threads": 1,
        "load_average": 1.62,
    }
    timed = _model("timed", 0.97, 900.0)
    timed["training"]["host"] = host
    row = gap_of(_document("trailer_env/Reverse-v1", 3, [timed]))
    assert row.host is not None and row.host.env_steps_per_s == 231_531.8
    assert row.reward_host == row.host  # learned from the reward alone: the same run
    assert (
        "| 15.0 min (232k steps/s, update 0.81 s, load 1.6) | no / yes | timed | 97 % "
        "| 15.0 min (232k steps/s, update 0.81 s, load 1.6) |"
    ) in time_to_ceiling_table([_document("trailer_env/Reverse-v1", 3, [timed])])
