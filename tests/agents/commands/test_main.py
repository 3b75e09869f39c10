"""The README's main command and the report command, end to end (small episode counts)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents.artifacts.shipped import committed_models
from agents.commands import main, report


def test_committed_models_are_small_and_carry_their_cards() -> None:
    models = committed_models("trailer_env/Reverse-v0", 2) + committed_models(main.ENV_ID, 2)
    assert any(model.stem == "dagger_reverse_v1_n2" for model in models)
    assert all(model.stem != "ppo_reverse_v1_memory_n2" for model in models)  # mismatch20
    models += committed_models(main.ENV_ID, 2, randomize="mismatch20")
    assert any(model.stem == "ppo_reverse_v1_memory_n2" for model in models)
    for model in models:
        # 64 x 64 agents take 0.2 MB, 256 x 256 ones (ppo_reverse_v1_n2) 1.7 MB with the
        # optimiser's state that --resume and --init-from continue from; 2.7 MB with a
        # 16-frame window (ppo_reverse_v1_memory_n2: a 152-wide first layer).
        assert model.stat().st_size < 3_000_000
        card = json.loads(model.with_suffix(".json").read_text())
        assert card["algo"] in ("ppo", "sac", "td3") and card["timesteps"] >= card["budget"]
        assert card["wall_time_s"] > 0 and isinstance(card["seed"], int)


def test_main_runs_on_reverse_v1_with_the_committed_agent(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main.main(["--out", str(tmp_path), "--episodes", "4"]) == 0
    captured = capsys.readouterr()
    printed = captured.out
    assert "evaluating on trailer_env/Reverse-v1: done, 12/12" in captured.err  # progress
    assert "main job done in" in printed
    assert "trailer_env/Reverse-v1, n = 2" in printed
    assert "| lqr |" in printed and "| dagger_reverse_v1_n2 |" in printed
    assert "| ppo_reverse_v1_n2 |" in printed  # the agent learned from reward, beside it
    assert "ceiling: 4/4 starts certified feasible" in printed
    for name in ("results.json", "results.md", "margins.png", "frames.png", "curves.png"):
        assert (tmp_path / name).is_file(), name
    document = json.loads((tmp_path / "results.json").read_text())
    names = [policy["name"] for policy in document["policies"]]
    assert names == [
        "zero",
        "random",
        "lqr",
        "mpc-replay",
        "dagger_reverse_v1_n2",
        "ppo_reverse_v1_n2",
    ]
    assert document["policies"][3]["safe_rate"] == 1.0  # the certified records, replayed
    for learned in document["policies"][-2:]:
        assert len(learned["training_seeds"]) == 3
        assert {entry["seed"] for entry in learned["training_seeds"]} == {0, 1, 2}
    assert document["env_id"] == "trailer_env/Reverse-v1"


@pytest.mark.slow
def test_main_with_the_planner(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main.main(["--out", str(tmp_path), "--episodes", "8", "--planner"]) == 0
    printed = capsys.readouterr().out
    assert "| mpc | oracle" in printed
    document = json.loads((tmp_path / "results.json").read_text())
    mpc = next(policy for policy in document["policies"] if policy["name"] == "mpc")
    assert mpc["safe_rate"] >= 0.75  # the planner's search is random: no exact figure


@pytest.mark.slow
def test_report_writes_tables_and_pictures(tmp_path: Path) -> None:
    assert (
        report.main(["--out", str(tmp_path), "--docs", str(tmp_path / "docs"), "--episodes", "4"])
        == 0
    )
    tables = (tmp_path / "tables.md").read_text()
    # One section per scenario, then the actuator sweep and the time to the ceiling.
    assert tables.count("#### ") == len(report.SCENARIOS) + 2
    assert "#### LQR on Reverse-v0 as the actuator gets stronger" in tables
    assert "#### Time to the ceiling" in tables
    for name in (
        "agents_curves.png",
        "agents_margins_reverse_v1_n2.png",
        "agents_frames_reverse_v1_n2.png",
    ):
        assert (tmp_path / "docs" / "img" / name).is_file(), name
    assert (tmp_path / "docs" / "generated" / "results_tables.md").read_text() == tables
