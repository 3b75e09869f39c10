"""Certifying the goal scenes (Dock-v0, Coast-v0) with the iLQR planner."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from agents.artifacts.certificates import (
    FEASIBLE,
    committed_actions,
    committed_certificate,
    markdown,
)
from agents.certification.certify import certify, planner_problem, replay
from agents.certification.search import restart_config
from agents.commands.certify import main
from agents.evaluation.ceiling import ceiling_note
from agents.oracles.ilqr import ILQRConfig
from trailer_env.scenes.dock import DockCore

DOCK = "trailer_env/Dock-v0"
COAST = "trailer_env/Coast-v0"
#: The committed certificates' feasible counts, witnesses included (seeds 1000-1099;
#: docs/agents.md).
CERTIFIED = {(DOCK, 1): 100, (DOCK, 2): 100, (COAST, 1): 100, (COAST, 2): 99}


@pytest.mark.parametrize("env_id", [pytest.param(DOCK, marks=pytest.mark.slow), COAST])
def test_certify_reaches_the_goal_and_the_record_replays(env_id: str) -> None:
    certified = certify(env_id, 1, [1000, 1001], restarts=0)
    certificate = certified.certificate
    assert certificate.feasible == 2 and certificate.open == 0
    assert certificate.not_recoverable == 0 and certificate.ceiling == 1.0
    assert certificate.planner.label == "ilqr" and certificate.success is not None
    assert set(certified.actions) == {1000, 1001}
    for start in certificate.starts:
        assert start.status == FEASIBLE and start.replay_success is True
        assert start.replay_safe is None
        record = certified.actions[start.seed]
        assert record.dtype == np.float64 and len(record) == start.planner_length
        outcome = replay(env_id, {"n_trailers": 1}, start.seed, record)
        assert outcome.success and outcome.feasible and outcome.length == start.planner_length
        # One step short of the record does not reach the goal: success is the record's.
        short = replay(env_id, {"n_trailers": 1}, start.seed, record[:-1])
        assert not short.success and not short.feasible
    assert "not applied" in markdown(certificate)


def test_exact_jacobians_certify_and_say_so() -> None:
    certified = certify(COAST, 1, [1000, 1001], ILQRConfig(jacobians="exact"), restarts=0)
    certificate = certified.certificate
    assert certificate.feasible == 2 and certificate.planner.jacobians == "exact"
    for start in certificate.starts:
        outcome = replay(COAST, {"n_trailers": 1}, start.seed, certified.actions[start.seed])
        assert outcome.success and outcome.length == start.planner_length
    default = certify(COAST, 1, [1000], restarts=0).certificate
    assert default.planner.jacobians == "differences"
    # The committed goal certificates came before the choice: they read as None.
    assert committed_certificate(COAST, 1).planner.jacobians is None  # type: ignore[union-attr]


@pytest.mark.parametrize(("env_id", "n"), [(DOCK, 1), (DOCK, 2), (COAST, 1), (COAST, 2)])
def test_committed_goal_records_replay_to_success(env_id: str, n: int) -> None:
    certificate = committed_certificate(env_id, n)
    records = committed_actions(env_id, n)
    assert certificate is not None and records is not None
    feasible = {start.seed: start for start in certificate.starts if start.feasible}
    assert set(records) == set(feasible)
    assert certificate.feasible == len(feasible) == CERTIFIED[env_id, n]
    assert certificate.open == 100 - CERTIFIED[env_id, n]
    assert certificate.not_recoverable == 0
    for seed in sorted(feasible)[:3]:
        outcome = replay(env_id, {"n_trailers": n}, seed, records[seed])
        assert outcome.feasible and outcome.length == len(records[seed])
        assert outcome.length == feasible[seed].planner_length
    assert ceiling_note(env_id, n, 100, 1000).startswith(
        f"ceiling: {certificate.feasible}/100 starts certified feasible"
    )


def test_bad_planners_are_refused_before_writing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    for argv, message in [
        (["--env", DOCK, "--planner", "mpc"], "does not steer it to trailer_env/Dock-v0's goal"),
        (["--env", COAST, "--planner", "mpc"], "certify it with --planner ilqr"),
        (["--env", DOCK, "--planner", "cem"], "invalid choice: 'cem'"),
        (["--env", "trailer_env/Reverse-v1", "--planner", "ilqr"], "use --planner mpc"),
        (["--env", "trailer_env/Reverse-v1", "--closed-loop", "dopri5"], "only for the goal"),
        (["--env", DOCK, "--closed-loop", "rk45"], "invalid choice: 'rk45'"),
        (["--env", "trailer_env/Reverse-v1", "--jacobians", "exact"], "only for ilqr"),
        (["--env", COAST, "--jacobians", "analytic"], "invalid choice: 'analytic'"),
    ]:
        with pytest.raises(SystemExit) as raised:
            main([*argv, "--seeds", "1000", "--out", str(out)])
        assert raised.value.code == 2
        assert message in capsys.readouterr().err
        assert not out.exists()
    assert planner_problem(DOCK, "ilqr") is None and planner_problem(DOCK, None) is None
    assert "unknown planner" in str(planner_problem(DOCK, "x"))
    with pytest.raises(ValueError, match="closed_loop must be one of"):
        certify(DOCK, 1, [1000], closed_loop="euler")


def test_restarts_lengthen_the_horizon_and_add_iterations() -> None:
    config = restart_config(ILQRConfig(), DockCore, 2)
    assert (config.horizon, config.iterations) == (200, 7)
    assert restart_config(ILQRConfig(horizon=60, iterations=1), DockCore, 1).horizon == 90
