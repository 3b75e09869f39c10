"""Witnesses: any policy's action record that replays to the scene's success certifies a start."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents.artifacts.certificates import (
    FEASIBLE,
    OPEN,
    committed_actions,
    committed_certificate,
    planner_records,
    read_actions,
    read_certificate,
    source_counts,
    start_source,
    write_certificate,
)
from agents.commands.certify import main
from agents.envs import make_vector_env
from agents.evaluation.witnesses import (
    add_witnesses,
    default_witnesses,
    sampled,
    warm_start_passes,
    witness_run,
)
from agents.oracles.certify_goals import replay_goal
from agents.policies import load_policy
from agents.policies.registry import PaddedPolicy
from agents.policies.sb3 import ModelPolicy, SampledPolicy

COAST = "trailer_env/Coast-v0"
DOCK = "trailer_env/Dock-v0"
V1 = "trailer_env/Reverse-v1"
#: Coast-v0, n = 1: the two starts the iLQR planner left open, which ppo_coast_n1 reaches.
HARD = [1077, 1098]
#: Every certified (scene, n) and its counts after the witness pass (docs/agents.md).
COMMITTED = {(V1, 1): 100, (V1, 2): 100, (V1, 3): 100, (V1, 4): 96, (DOCK, 1): 100,
             (DOCK, 2): 100, (COAST, 1): 100, (COAST, 2): 99}  # fmt: skip


def _open_certificate(env_id: str, n: int, seeds: list[int], planner: str) -> dict[str, Any]:
    starts = [
        {"seed": seed, "status": OPEN, "screen_stroke_fraction": None, "planner_length": 7}
        for seed in seeds
    ]
    return {
        "env_id": env_id,
        "env_kwargs": {"n_trailers": n},
        "seeds": [min(seeds), max(seeds)],
        "episodes": len(seeds),
        "planner": {
            "name": planner,
            "first_pass_safe": 0,
            "first_pass_wall_time_s": 0.0,
            "wall_time_s": 0.0,
            "restarts": 0,
        },
        "screen": {"applied": False, "wall_time_s": 0.0},
        "feasible": 0,
        "not_recoverable": 0,
        "open": len(seeds),
        "ceiling": 0.0,
        "starts": starts,
        "actions": {},
    }


def test_an_agents_record_is_a_witness_and_replays() -> None:
    certificate = _open_certificate(COAST, 1, HARD, "ilqr")
    upgraded = add_witnesses(certificate, ["zero", "ppo_coast_n1"], closed_loop=False)
    assert (upgraded["feasible"], upgraded["open"], upgraded["ceiling"]) == (2, 0, 1.0)
    assert upgraded["sources"] == {"ppo_coast_n1": 2}
    runs = upgraded["witnesses"]["runs"]
    assert runs == [
        {"source": "zero", "tried": 2, "solved": 0},
        {"source": "ppo_coast_n1", "tried": 2, "solved": 2},
    ]
    assert certificate["open"] == 2 and certificate["actions"] == {}  # not changed in place
    for start in upgraded["starts"]:
        record = upgraded["actions"][start["seed"]]
        assert start["status"] == FEASIBLE and start["source"] == "ppo_coast_n1"
        assert record.dtype == np.float64 and record.shape == (start["witness_length"], 1)
        replayed = replay_goal(COAST, {"n_trailers": 1}, start["seed"], record)
        assert replayed == (True, start["witness_length"])
        assert replay_goal(COAST, {"n_trailers": 1}, start["seed"], record[:-1])[0] is False


def test_the_record_is_the_applied_action() -> None:
    def pushing(obs: np.ndarray) -> np.ndarray:
        return np.full((len(obs), 1), 3.0, dtype=np.float32)  # clipped to 1 by the env

    run = witness_run(pushing, COAST, {"n_trailers": 1}, [1000, 1003])
    assert run.actions.dtype == np.float64
    for row in range(2):
        played = run.actions[row, : run.lengths[row]]
        assert np.all(played == 1.0) and np.all(run.actions[row, run.lengths[row] :] == 0.0)
    # Full push straightens start 1003 in 13 steps; 1000 ends unsuccessful after 25.
    assert run.lengths.tolist() == [25, 13] and run.success.tolist() == [False, True]
    assert replay_goal(COAST, {"n_trailers": 1}, 1003, run.actions[1, :13]) == (True, 13)
    with pytest.raises(ValueError, match="at least one seed"):
        witness_run(pushing, COAST, {"n_trailers": 1}, [])


def test_source_round_trips_through_the_files(tmp_path: Path) -> None:
    certificate = _open_certificate(COAST, 1, [*HARD, 1000], "ilqr")
    certificate["starts"][2].update(status=FEASIBLE)  # a planner's start, from an old file
    certificate.update(feasible=1, open=2, ceiling=1 / 3)
    certificate["actions"] = {1000: committed_actions(COAST, 1)[1000]}  # type: ignore[index]
    assert start_source(certificate, certificate["starts"][2]) == "ilqr"
    assert start_source(certificate, certificate["starts"][0]) is None
    upgraded = add_witnesses(certificate, ["ppo_coast_n1"], closed_loop=False)
    write_certificate(upgraded, tmp_path / "cert", overwrite=False)
    document = read_certificate(tmp_path / "cert" / "certificate.json")
    assert [start["source"] for start in document["starts"]] == ["ppo_coast_n1"] * 2 + ["ilqr"]
    assert document["sources"] == {"ilqr": 1, "ppo_coast_n1": 2}
    records = read_actions(tmp_path / "cert" / "actions.npz")
    for seed, record in upgraded["actions"].items():
        assert records[seed].tobytes() == record.tobytes()
    text = (tmp_path / "cert" / "certificate.md").read_text()
    assert "feasible by source: ilqr 1, ppo_coast_n1 2" in text
    assert "| 1077 | feasible | ppo_coast_n1 |" in text
    edited = json.loads((tmp_path / "cert" / "certificate.json").read_text())
    edited["sources"]["ilqr"] = 2
    (tmp_path / "bad.json").write_text(json.dumps(edited))
    with pytest.raises(ValueError, match="sources must count the feasible starts"):
        read_certificate(tmp_path / "bad.json")
    edited = json.loads((tmp_path / "cert" / "certificate.json").read_text())
    edited["starts"][0].update(status=OPEN, source="lqr")
    edited.update(feasible=2, open=1, ceiling=2 / 3)
    (tmp_path / "bad.json").write_text(json.dumps(edited))
    with pytest.raises(ValueError, match="only on a feasible start"):
        read_certificate(tmp_path / "bad.json")


def test_the_command_adds_witnesses_to_a_certificate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = tmp_path / "base"
    write_certificate(_open_certificate(COAST, 1, HARD, "ilqr"), base, overwrite=False)
    out = tmp_path / "out"
    for argv, message in [
        (["--env", DOCK], "--env: trailer_env/Dock-v0 is not the certificate's"),
        (["--seeds", "1077"], "not with --from-certificate"),
        (["--witnesses", "nobody"], "unknown policy 'nobody'"),
        (["--no-witnesses"], "only adds witnesses"),
        (["--warm-start", "lqr", "lqr"], "two specs of one label"),
    ]:
        with pytest.raises(SystemExit) as raised:
            main(["--from-certificate", str(base / "certificate.json"), *argv, "--out", str(out)])
        assert raised.value.code == 2 and message in capsys.readouterr().err
        assert not out.exists()
    with pytest.raises(SystemExit):
        main(["--env", V1, "--warm-start", "--out", str(out)])
    assert "goal scenes only" in capsys.readouterr().err
    argv = ["--from-certificate", str(base / "certificate.json"), "--witnesses", "ppo_coast_n1"]
    assert main([*argv, "--out", str(out)]) == 0
    document = read_certificate(out / "certificate.json")
    assert (document["feasible"], document["sources"]) == (2, {"ppo_coast_n1": 2})
    closed = document["witnesses"]["closed_loop"]
    assert (closed["integrator"], closed["of"], closed["success"]) == ("dopri5", 2, 2)
    assert all(start["witness_closed_loop_success"] for start in document["starts"])
    assert set(read_actions(out / "actions.npz")) == set(HARD)


def test_the_oracle_row_replays_the_planners_records_only(tmp_path: Path) -> None:
    certificate = _open_certificate(COAST, 1, [*HARD, 1000], "ilqr")
    certificate["starts"][2].update(status=FEASIBLE)
    certificate.update(feasible=1, open=2, ceiling=1 / 3)
    certificate["actions"] = {1000: committed_actions(COAST, 1)[1000]}  # type: ignore[index]
    upgraded = add_witnesses(certificate, ["ppo_coast_n1"], closed_loop=False)
    write_certificate(upgraded, tmp_path / "cert", overwrite=False)
    (tmp_path / "cert" / "certificate.json").rename(tmp_path / "coast_n1.json")
    (tmp_path / "cert" / "actions.npz").rename(tmp_path / "coast_n1_actions.npz")
    assert sorted(committed_actions(COAST, 1, tmp_path)) == [1000, *HARD]  # type: ignore[arg-type]
    assert sorted(planner_records(COAST, 1, tmp_path)) == [1000]  # type: ignore[arg-type]


def test_the_default_witnesses_are_the_baselines_and_the_committed_models() -> None:
    names = [Path(spec).stem for spec in default_witnesses(DOCK, 2)]
    assert names == [
        "zero",
        "random",
        "lqr",
        "ppo_dock_n2",
        "ppo_dock_n2_s0",
        "ppo_dock_n2_s1",
        "ppo_dock_n2_s2",
    ]
    generalist = [Path(spec).stem for spec in default_witnesses(V1, 3)]
    assert "dagger_reverse_v1_general" in generalist and "dagger_reverse_v1_n3" in generalist


@pytest.mark.parametrize(("env_id", "n"), sorted(COMMITTED))
def test_no_committed_policy_solves_an_open_start(env_id: str, n: int) -> None:
    certificate = committed_certificate(env_id, n)
    assert certificate is not None
    assert certificate["feasible"] == COMMITTED[env_id, n]
    assert certificate["seeds"] == [1000, 1099] and certificate["episodes"] == 100
    left = [start["seed"] for start in certificate["starts"] if start["status"] != FEASIBLE]
    assert len(left) == 100 - COMMITTED[env_id, n]
    assert sum(source_counts(certificate).values()) == certificate["feasible"]
    if not left:
        return
    for spec in default_witnesses(env_id, n):
        policy = load_policy(spec, env_id, {"n_trailers": n})
        run = witness_run(policy, env_id, {"n_trailers": n}, left)
        assert not run.success.any(), (spec, run.success.tolist())


def test_warm_start_passes_accumulate_and_read_the_old_single_block() -> None:
    first, second = {"specs": ["a"], "open_before": 12}, {"specs": ["b"], "open_before": 11}
    assert warm_start_passes(None) == [] and warm_start_passes({"runs": []}) == []
    assert warm_start_passes({"warm_start": first}) == [first]  # a certificate of before
    assert warm_start_passes({"warm_start": first, "warm_starts": [second]}) == [first, second]
    assert warm_start_passes({"warm_starts": [first, second, "junk"]}) == [first, second]
    assert warm_start_passes({"warm_starts": None}) == warm_start_passes({"warm_starts": 3}) == []


def test_a_sampled_draw_of_a_model_is_a_witness_and_replays() -> None:
    # ppo_dock_n2 fails 1032 acting on its mean and docks it in 22 of 64 sampled draws;
    # 1021 fails its 8 draws here (the draws are seeded per batch, so they depend on its rows).
    certificate = _open_certificate(DOCK, 2, [1021, 1032], "ilqr")
    upgraded = add_witnesses(certificate, ["lqr", "ppo_dock_n2"], samples=8)
    assert (upgraded["feasible"], upgraded["open"]) == (1, 1)
    assert upgraded["sources"] == {"ppo_dock_n2 (sampled)": 1}
    assert upgraded["witnesses"]["runs"][2:] == [
        {"source": "ppo_dock_n2 (sampled)", "tried": 2, "solved": 1, "draws": 8, "sample_seed": 0}
    ]  # a baseline is not sampled
    start = upgraded["starts"][1]
    record = upgraded["actions"][1032]
    # Which draw docks it is a float outcome of the host's compiled kernels (draw 0 here).
    assert start["witness_draw"] in range(8) and start["witness_closed_loop_success"] is True
    assert replay_goal(DOCK, {"n_trailers": 2}, 1032, record) == (True, start["witness_length"])
    again = add_witnesses(certificate, ["ppo_dock_n2"], samples=8, closed_loop=False)
    assert np.array_equal(again["actions"][1032], record)  # the draws are seeded
    other = add_witnesses(certificate, ["ppo_dock_n2"], samples=8, sample_seed=1, closed_loop=False)
    assert not np.array_equal(other["actions"].get(1032, np.empty(0)), record)  # other draws
    with pytest.raises(ValueError, match=r"samples must be in 0 \.\. 1024"):
        add_witnesses(certificate, ["ppo_dock_n2"], samples=1025)


def test_sampled_actions_are_seeded_and_leave_the_global_generator_alone() -> None:
    import torch

    model = load_policy("ppo_dock_n2", DOCK, {"n_trailers": 2})
    assert isinstance(model, ModelPolicy)
    envs = make_vector_env(DOCK, 64, {"n_trailers": 2})
    obs, _ = envs.reset(seed=1000)
    before = torch.get_rng_state()
    first = [SampledPolicy(model, 3)(obs) for _ in range(2)]
    assert torch.equal(torch.get_rng_state(), before)
    assert np.array_equal(first[0], first[1])
    assert not np.array_equal(first[0], SampledPolicy(model, 4)(obs))
    assert not np.allclose(first[0], model(obs))  # not the mean


def test_models_are_sampled_alone_or_padded_and_baselines_are_not() -> None:
    kwargs = {"n_trailers": 2}
    padded = sampled(load_policy("dagger_reverse_v1_general", V1, kwargs), 0)
    assert isinstance(padded, PaddedPolicy) and isinstance(padded.policy, SampledPolicy)
    assert (padded.n, padded.top) == (2, 3)
    assert isinstance(sampled(load_policy("ppo_reverse_v1_n2", V1, kwargs), 0), SampledPolicy)
    assert sampled(load_policy("lqr", V1, kwargs), 0) is None
    assert sampled(load_policy("dagger_reverse_v1_sequence", V1, kwargs), 0) is None
