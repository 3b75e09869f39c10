"""Witnesses: any policy's action record that replays to the scene's success certifies a start."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from agents.artifacts.action_records import read_actions
from agents.artifacts.certificates import (
    FEASIBLE,
    OPEN,
    Certified,
    WarmStartPass,
    WitnessesPart,
    WitnessTally,
    committed_actions,
    committed_certificate,
    planner_records,
    read_certificate,
    write_certificate,
)
from agents.certification.certify import replay
from agents.certification.witnesses import (
    add_witnesses,
    default_witnesses,
    sampled,
    witness_run,
)
from agents.commands.certify import main
from agents.envs import make_vector_env
from agents.policies import load_policy
from agents.policies.registry import PaddedPolicy
from agents.policies.sb3 import ModelPolicy, SampledPolicy
from tests.agents.helpers import fake_certified
from trailer_env.observation import flat_observation

COAST = "trailer_env/Coast-v0"
DOCK = "trailer_env/Dock-v0"
V1 = "trailer_env/Reverse-v1"
#: Coast-v0, n = 1: the two starts the iLQR planner left open, which ppo_coast_n1 reaches.
HARD = [1077, 1098]
#: Every certified (scene, n) and its counts after the witness pass (docs/agents.md).
COMMITTED = {(V1, 1): 100, (V1, 2): 100, (V1, 3): 100, (V1, 4): 96, (DOCK, 1): 100,
             (DOCK, 2): 100, (COAST, 1): 100, (COAST, 2): 99}  # fmt: skip


def _reached(
    env_id: str, env_kwargs: dict[str, int], seed: int, record: np.ndarray
) -> tuple[bool, int]:
    """A replay's (ended in the scene's success, steps played)."""
    outcome = replay(env_id, env_kwargs, seed, record)
    return outcome.success, outcome.length


def _open_certificate(env_id: str, n: int, seeds: list[int], planner: str) -> Certified:
    return fake_certified(seeds, env_id, n, status=OPEN, planner=planner)


def _with_planner_start(certified: Certified, seed: int) -> Certified:
    """``certified`` with start ``seed`` feasible by the planner, as a file written before
    sources were kept (no ``source``), its committed record beside it."""
    certificate = certified.certificate
    starts = tuple(
        start.replace(status=FEASIBLE) if start.seed == seed else start
        for start in certificate.starts
    )
    records = committed_actions(certificate.env_id, certificate.n_trailers)
    assert records is not None
    return Certified(certificate.with_starts(starts), {seed: records[seed]})


def test_an_agents_record_is_a_witness_and_replays() -> None:
    certificate = _open_certificate(COAST, 1, HARD, "ilqr")
    upgraded = add_witnesses(certificate, ["zero", "ppo_coast_n1"], closed_loop=False)
    result = upgraded.certificate
    assert (result.feasible, result.open, result.ceiling) == (2, 0, 1.0)
    assert result.sources == {"ppo_coast_n1": 2}
    assert result.witnesses is not None and result.witnesses.runs == (
        WitnessTally(source="zero", tried=2, solved=0),
        WitnessTally(source="ppo_coast_n1", tried=2, solved=2),
    )
    assert certificate.certificate.open == 2 and certificate.actions == {}  # not changed
    for start in result.starts:
        record = upgraded.actions[start.seed]
        assert start.status == FEASIBLE and start.source == "ppo_coast_n1"
        assert start.replay_success is True and start.witness_length is not None
        assert record.dtype == np.float64 and record.shape == (start.witness_length, 1)
        replayed = _reached(COAST, {"n_trailers": 1}, start.seed, record)
        assert replayed == (True, start.witness_length)
        assert _reached(COAST, {"n_trailers": 1}, start.seed, record[:-1])[0] is False


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
    assert _reached(COAST, {"n_trailers": 1}, 1003, run.actions[1, :13]) == (True, 13)
    with pytest.raises(ValueError, match="at least one seed"):
        witness_run(pushing, COAST, {"n_trailers": 1}, [])


def test_source_round_trips_through_the_files(tmp_path: Path) -> None:
    certificate = _with_planner_start(_open_certificate(COAST, 1, [*HARD, 1000], "ilqr"), 1000)
    starts = certificate.certificate.starts
    assert certificate.certificate.source_of(starts[2]) == "ilqr"
    assert certificate.certificate.source_of(starts[0]) is None
    upgraded = add_witnesses(certificate, ["ppo_coast_n1"], closed_loop=False)
    write_certificate(upgraded, tmp_path / "cert", overwrite=False)
    document = read_certificate(tmp_path / "cert" / "certificate.json")
    assert [start.source for start in document.starts] == ["ppo_coast_n1"] * 2 + ["ilqr"]
    assert document.sources == {"ilqr": 1, "ppo_coast_n1": 2}
    records = read_actions(tmp_path / "cert" / "actions.npz")
    for seed, record in upgraded.actions.items():
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
    assert (document.feasible, document.sources) == (2, {"ppo_coast_n1": 2})
    assert document.witnesses is not None and document.witnesses.closed_loop is not None
    closed = document.witnesses.closed_loop
    assert (closed.integrator, closed.of, closed.success) == ("dopri5", 2, 2)
    assert all(start.witness_closed_loop_success for start in document.starts)
    assert set(read_actions(out / "actions.npz")) == set(HARD)


def test_the_oracle_row_replays_the_planners_records_only(tmp_path: Path) -> None:
    certificate = _with_planner_start(_open_certificate(COAST, 1, [*HARD, 1000], "ilqr"), 1000)
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
    assert certificate.feasible == COMMITTED[env_id, n]
    assert certificate.seeds == (1000, 1099) and certificate.episodes == 100
    left = [start.seed for start in certificate.starts if not start.feasible]
    assert len(left) == 100 - COMMITTED[env_id, n]
    assert sum(certificate.source_counts().values()) == certificate.feasible
    if not left:
        return
    for spec in default_witnesses(env_id, n):
        policy = load_policy(spec, env_id, {"n_trailers": n})
        run = witness_run(policy, env_id, {"n_trailers": n}, left)
        assert not run.success.any(), (spec, run.success.tolist())


def test_warm_start_passes_accumulate_and_read_the_old_single_block() -> None:
    def one(specs: list[str], open_before: int) -> dict[str, object]:
        return {"specs": specs, "splits": [0.5], "open_before": open_before, "attempts": [],
                "wall_time_s": 0.0}  # fmt: skip

    first, second = one(["a"], 12), one(["b"], 11)
    block = {"runs": [], "success": "replayed", "wall_time_s": 0.0}
    assert WitnessesPart.from_json(block).warm_start_passes() == ()
    old = WitnessesPart.from_json({**block, "warm_start": first})  # a certificate of before
    assert old.warm_start_passes() == (WarmStartPass.from_json(first),)
    both = WitnessesPart.from_json({**block, "warm_start": first, "warm_starts": [second]})
    assert [p.open_before for p in both.warm_start_passes()] == [12, 11]
    with pytest.raises(ValueError, match="warm_starts"):
        WitnessesPart.from_json({**block, "warm_starts": [first, "junk"]})


def test_a_sampled_draw_of_a_model_is_a_witness_and_replays() -> None:
    # ppo_dock_n2 fails 1032 acting on its mean and docks it in 22 of 64 sampled draws;
    # 1021 fails its 8 draws here (the draws are seeded per batch, so they depend on its rows).
    certificate = _open_certificate(DOCK, 2, [1021, 1032], "ilqr")
    upgraded = add_witnesses(certificate, ["lqr", "ppo_dock_n2"], samples=8)
    result = upgraded.certificate
    assert (result.feasible, result.open) == (1, 1)
    assert result.sources == {"ppo_dock_n2 (sampled)": 1}
    assert result.witnesses is not None and result.witnesses.runs[2:] == (
        WitnessTally(source="ppo_dock_n2 (sampled)", tried=2, solved=1, draws=8, sample_seed=0),
    )  # a baseline is not sampled
    start = result.starts[1]
    record = upgraded.actions[1032]
    # Which draw docks it is a float outcome of the host's compiled kernels (draw 0 here).
    assert start.witness_draw in range(8) and start.witness_closed_loop_success is True
    assert _reached(DOCK, {"n_trailers": 2}, 1032, record) == (True, start.witness_length)
    again = add_witnesses(certificate, ["ppo_dock_n2"], samples=8, closed_loop=False)
    assert np.array_equal(again.actions[1032], record)  # the draws are seeded
    other = add_witnesses(certificate, ["ppo_dock_n2"], samples=8, sample_seed=1, closed_loop=False)
    assert not np.array_equal(other.actions.get(1032, np.empty(0)), record)  # other draws
    with pytest.raises(ValueError, match=r"samples must be in 0 \.\. 1024"):
        add_witnesses(certificate, ["ppo_dock_n2"], samples=1025)


def test_sampled_actions_are_seeded_and_leave_the_global_generator_alone() -> None:
    import torch

    model = load_policy("ppo_dock_n2", DOCK, {"n_trailers": 2})
    assert isinstance(model, ModelPolicy)
    envs = make_vector_env(DOCK, 64, {"n_trailers": 2})
    obs = flat_observation(envs.reset(seed=1000)[0], "the test")
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


def test_a_model_with_a_memory_plays_its_window_and_is_sampled_with_it(tmp_path: Path) -> None:
    """A witness whose card holds ``history`` plays in an env with that window; its records
    replay in the certificate's env (the window changes what it reads, not the dynamics)."""
    committed = Path("agents/certificates/reverse_v1_mismatch20_n3.json")
    argv = ["--from-certificate", str(committed), "--witnesses", "dagger_reverse_v1_memory"]
    assert main([*argv, "--witness-samples", "2", "--out", str(tmp_path / "out")]) == 0
    document = read_certificate(tmp_path / "out" / "certificate.json")
    assert document.witnesses is not None
    runs = [(run.source, run.tried) for run in document.witnesses.runs]
    assert runs[-2:] == [("dagger_reverse_v1_memory", 2), ("dagger_reverse_v1_memory (sampled)", 2)]
    kwargs = {"n_trailers": 2, "randomize": "mismatch20", "history": 16}
    padded = sampled(load_policy("dagger_reverse_v1_memory", V1, kwargs), 0)
    assert isinstance(padded, PaddedPolicy) and (padded.history, padded.top) == (16, 3)
