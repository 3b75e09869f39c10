"""The certification entry point: statuses, float64 records that replay, one replay that
reads the scene's objective, refusal to overwrite."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from agents.artifacts.certificates import FEASIBLE, NOT_RECOVERABLE, write_certificate
from agents.certification.certify import certify, replay
from agents.commands.certify import main, parse_seeds
from agents.oracles.ilqr import ILQRConfig
from agents.oracles.planner import PlannerConfig

V1 = "trailer_env/Reverse-v1"
SMALL = PlannerConfig(samples=4, elites=1, iterations=1, tail=30)


def test_parse_seeds() -> None:
    assert parse_seeds("1000-1003") == [1000, 1001, 1002, 1003]
    assert parse_seeds("5") == [5]
    assert parse_seeds("1,4-5") == [1, 4, 5]
    with pytest.raises(ValueError, match="LOW <= HIGH"):
        parse_seeds("9-3")
    with pytest.raises(ValueError, match="more than 3 integers"):
        parse_seeds("1-4", maximum=3)


def test_certified_sequence_replays_identically(tmp_path: Path) -> None:
    certified = certify(V1, 1, [2000, 2002], SMALL, restarts=0)
    assert certified.certificate.feasible == 2
    assert certified.certificate.ceiling == 1.0
    assert certified.certificate.success is None  # a survival scene's certificate
    write_certificate(certified, tmp_path / "cert", overwrite=False)
    document = json.loads((tmp_path / "cert" / "certificate.json").read_text())
    start = document["starts"][0]
    assert start["status"] == FEASIBLE and start["replay_safe"] is True
    sequence = np.load(tmp_path / "cert" / start["actions_file"], allow_pickle=False)
    assert sequence.dtype == np.float64
    assert sequence.shape == (400,)
    first = replay(V1, {"n_trailers": 1}, 2000, sequence)
    second = replay(V1, {"n_trailers": 1}, 2000, sequence)
    assert first == second
    assert first.safe and first.feasible and first.length == 400
    # A survival record cut short is safe but not the full episode.
    cut = replay(V1, {"n_trailers": 1}, 2000, sequence[:100])
    assert cut.safe and cut.length == 100 and not cut.feasible


def test_refuses_to_overwrite(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cert"
    out.mkdir()
    with pytest.raises(SystemExit) as error:
        main(["--env", V1, "--n-trailers", "1", "--seeds", "2000", "--out", str(out)])
    assert error.value.code == 2
    assert "--overwrite" in capsys.readouterr().err


def test_restarts_plan_only_the_starts_not_kept_safe() -> None:
    # Reverse-v0, n = 3: seed 2004 needs 1.5 strokes (not recoverable), 2009 needs 0.33.
    certificate = certify("trailer_env/Reverse-v0", 3, [2004, 2009], SMALL, restarts=2).certificate
    hard, easy = certificate.starts
    assert hard.status == NOT_RECOVERABLE and hard.planner_attempts == 3
    assert easy.status == FEASIBLE and easy.planner_attempts == 1
    assert certificate.planner.restarts == 2
    assert certificate.planner.first_pass_safe == 1
    assert certificate.screen_upper_estimate == 0.5
    with pytest.raises(ValueError, match="restarts"):
        certify(V1, 1, [2000], SMALL, restarts=-1)


def test_the_scene_s_objective_chooses_what_certify_accepts() -> None:
    """Reverse is survived (mpc), Dock reached (ilqr), Heading has no certifying planner:
    each refusal comes before anything is simulated."""
    with pytest.raises(TypeError, match="config must be PlannerConfig for trailer_env/Rev"):
        certify(V1, 1, [2000], ILQRConfig())
    with pytest.raises(TypeError, match="config must be ILQRConfig for trailer_env/Dock-v0"):
        certify("trailer_env/Dock-v0", 1, [2000], SMALL)
    with pytest.raises(ValueError, match="closed_loop: only for the goal scenes"):
        certify(V1, 1, [2000], SMALL, closed_loop="dopri5")
    with pytest.raises(ValueError, match="randomize: certifying randomised physics"):
        certify("trailer_env/Dock-v0", 1, [2000], randomize="mismatch20")
    with pytest.raises(ValueError, match="no planner certifies trailer_env/Heading-v0"):
        certify("trailer_env/Heading-v0", 1, [2000])
    with pytest.raises(ValueError, match="seeds: certify at least one start"):
        certify(V1, 1, [])
