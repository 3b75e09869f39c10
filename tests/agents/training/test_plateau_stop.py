"""``agents.train --stop-on-plateau``: a flat validation curve ends the run early."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from agents.artifacts.curves import read_curve
from agents.commands import train
from agents.evaluation.learning_curves import is_flat, trend
from agents.training import callbacks
from agents.training.callbacks import PlateauStop
from tests.agents.helpers import tiny_ppo_hyperparams


def test_plateau_stop_hook() -> None:
    stop = PlateauStop("safe_rate", 3, 0.05, previous=[(0, 0.1)])
    evaluations = ((10, 0.5), (20, 0.52), (30, 0.56), (40, 0.9))
    stops = [stop(step, {"safe_rate": rate}) for step, rate in evaluations]
    # At 30 the trend's fit has four evaluations, under its minimum of five: no trend.
    assert stops == [False, False, True, True]
    assert stop.stopped_at == 30


def test_a_run_still_at_its_first_level_is_not_stopped() -> None:
    stop = PlateauStop("safe_rate", 3, 0.05)
    rates = (0.0, 0.0, 0.0, 0.02, 0.0, 0.4, 0.9, 0.92, 0.9, 0.9, 0.91, 0.9, 0.9, 0.92)
    stops = [stop(step, {"safe_rate": rate}) for step, rate in enumerate(rates)]
    # Flat at 0 from the third evaluation, but that is the start: no stop there. Flat at
    # 0.9 at step 8 too, but the line through the last five points (4-8) still climbs
    # out of the jump from 0.4; at 9 (points 5-9) it no longer rises by the t-test.
    assert stops == [False] * 9 + [True] * 5 and stop.stopped_at == 9


#: TD3 on Reverse-v1 n = 2, seed 2: its validation safe rate every 25k steps,
#: from 175k (0 before), as run with ``--stop-on-plateau 5,0.05``.
TD3_N2_SEED2 = (0.04, 0.44, 0.44, 0.52, 0.7, 0.74, 0.62, 0.66, 0.86, 0.68,
                0.84, 0.84, 0.88, 0.9, 0.94, 0.9, 0.9)  # fmt: skip


def test_a_flat_window_on_a_climb_is_not_a_plateau() -> None:
    """The plateau rule alone stopped that run at 575k steps (five evaluations at
    0.88-0.94), where its last third still rose by +0.18: not a plateau any more."""
    rates = [0.0] * 7 + list(TD3_N2_SEED2)
    steps = [25_000 * k for k in range(len(rates))]
    assert steps[-1] == 575_000 and is_flat(rates, 5, 0.05)
    end = trend(steps, rates)
    assert end is not None and end.rising and end.change == pytest.approx(0.18, abs=0.01)
    stop = PlateauStop("safe_rate", 5, 0.05, previous=list(zip(steps, rates, strict=True))[:-1])
    assert stop(steps[-1], {"safe_rate": rates[-1]}) is False and stop.stopped_at is None
    # Held at 0.9 from there, the end flattens and the run stops, once.
    held = [stop(575_000 + 25_000 * k, {"safe_rate": 0.9}) for k in range(1, 21)]
    first = held.index(True)
    assert held[first:] == [True] * (len(held) - first) and first > 0
    assert stop.stopped_at == 575_000 + 25_000 * (first + 1)
    settled = trend(stop.steps[: 24 + first + 1], stop.values[: 24 + first + 1])
    assert settled is not None and not settled.rising


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
