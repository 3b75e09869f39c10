"""``agents.evaluate`` takes the scene from the first model's card; usage names the script."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from agents.commands import evaluate, options, report
from agents.progress import plural


def test_the_card_names_the_scene_when_env_is_not_given(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "eval"
    argv = ["--policy", "ppo_reverse_n2", "lqr", "--episodes", "1", "--no-plots", "--out", str(out)]
    assert evaluate.main(argv) == 0
    captured = capsys.readouterr()
    assert "evaluate: trailer_env/Reverse-v0, n = 2 from the card of ppo_reverse_n2" in (
        captured.err
    )
    assert "evaluated 2 policies in" in captured.out
    document = json.loads((out / "results.json").read_text())
    assert document["env_id"] == "trailer_env/Reverse-v0"
    assert document["env_kwargs"]["n_trailers"] == 2
    assert (
        (out / "results.md")
        .read_text()
        .startswith("trailer_env/Reverse-v0, n = 2: 1 episode, seeds 1000..1000\n")
    )


def test_given_env_wins_and_a_mismatch_is_still_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["--policy", "ppo_reverse_n2", "--env", "trailer_env/Reverse-v1", "--episodes", "1"]
    with pytest.raises(SystemExit) as raised:
        evaluate.main([*argv, "--no-plots", "--out", str(tmp_path / "eval")])
    assert raised.value.code == 2
    err = capsys.readouterr().err
    assert "evaluate: n = 2 from the card of ppo_reverse_n2\n" in err  # the env was given
    assert "was trained on trailer_env/Reverse-v0 with n_trailers = 2, not" in err
    assert not (tmp_path / "eval").exists()


def test_env_from_cards() -> None:
    assert evaluate.env_from_cards(["zero", "lqr"]) == (None, None, None, 0)
    assert evaluate.env_from_cards(["lqr", "ppo_dock_n1", "ppo_reverse_n2"]) == (
        "trailer_env/Dock-v0",
        1,
        "ppo_dock_n1",
        0,
    )
    # A generalist's card holds a range of counts: the scene, and no n.
    assert evaluate.env_from_cards(["dagger_reverse_v1_general"]) == (
        "trailer_env/Reverse-v1",
        None,
        "dagger_reverse_v1_general",
        0,
    )
    # An unreadable model is passed over here (its load reports it).
    assert evaluate.env_from_cards(["absent/model.zip"]) == (None, None, None, 0)


def test_usage_names_the_console_script_that_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "argv", ["/venv/bin/trailer-env-evaluate"])
    assert evaluate.build_parser().format_usage().startswith("usage: trailer-env-evaluate ")
    monkeypatch.setattr(sys, "argv", ["/repo/agents/report.py"])
    assert report.build_parser().format_usage().startswith("usage: python -m agents.report ")
    assert options.program("agents.report") == "python -m agents.report"


def test_plural() -> None:
    assert [plural(1, "step"), plural(2, "step"), plural(0, "runner")] == [
        "1 step",
        "2 steps",
        "0 runners",
    ]
    assert [plural(1, "policy", "policies"), plural(3, "policy", "policies")] == [
        "1 policy",
        "3 policies",
    ]
