"""``agents.train --stop-on-plateau``: a flat validation curve ends the run early."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from agents.artifacts.curves import read_curve
from agents.commands import train
from agents.training import callbacks
from agents.training.callbacks import PlateauStop
from tests.agents.helpers import tiny_ppo_hyperparams


def test_plateau_stop_hook() -> None:
    stop = PlateauStop("safe_rate", 3, 0.05, previous=[0.1])
    evaluations = ((10, 0.5), (20, 0.52), (30, 0.56), (40, 0.9))
    stops = [stop(step, {"safe_rate": rate}) for step, rate in evaluations]
    assert stops == [False, False, True, True]
    assert stop.stopped_at == 30


def test_a_run_still_at_its_first_level_is_not_stopped() -> None:
    stop = PlateauStop("safe_rate", 3, 0.05)
    rates = (0.0, 0.0, 0.0, 0.02, 0.0, 0.4, 0.9, 0.92, 0.9)
    stops = [stop(step, {"safe_rate": rate}) for step, rate in enumerate(rates)]
    # Flat at 0 from the third evaluation, but that is the start: no stop until 0.9.
    assert stops == [False] * 8 + [True] and stop.stopped_at == 8


def test_a_flat_curve_stops_the_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    tiny_ppo_hyperparams(tmp_path / "hp", "trailer_env/Reverse-v1")
    run = tmp_path / "run"
    # The validation rates are set to 0, 0.5, 0.5, ...: flat, and off the start, at 1024.
    rates = iter([0.0] + [0.5] * 100)

    real = callbacks.summarize

    def rigged(results: Any) -> dict[str, Any]:
        return {**real(results), "safe_rate": next(rates)}

    monkeypatch.setattr(callbacks, "summarize", rigged)
    code = train.main(
        [
            "--env",
            "trailer_env/Reverse-v1",
            "--algo",
            "ppo",
            "--n-trailers",
            "1",
            "--hyperparams",
            str(tmp_path / "hp"),
            "--run-dir",
            str(run),
            "--timesteps",
            "8192",
            "--eval-freq",
            "512",
            "--eval-episodes",
            "2",
            "--stop-on-plateau",
            "2,0.05",
            "--no-progress",
        ]
    )
    assert code == 0
    assert [row["timesteps"] for row in read_curve(run / "evaluations.csv")] == [0, 512, 1024]
    card = json.loads((run / "final_model.json").read_text())
    # Stopped at the first step of the next rollout (8 environments).
    assert (card["stopped_on_plateau_at"], card["timesteps"]) == (1024, 1032)
    assert "stopped at 1024 steps" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        train.main(["--env", "trailer_env/Reverse-v1", "--algo", "ppo", "--stop-on-plateau", "5"])
    assert "expected WINDOW,EPS" in capsys.readouterr().err
