"""The committed certificates' action records: replayed, they keep exactly the certified starts."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from agents.artifacts.action_records import write_actions
from agents.artifacts.certificates import (
    FEASIBLE,
    actions_path,
    committed_actions,
    committed_certificate,
    planner_records,
)
from agents.certification.replays import replays_to_success
from agents.evaluation.metrics import rollout
from agents.policies import load_policy

REVERSE_V1 = "trailer_env/Reverse-v1"


@pytest.mark.parametrize("n", [1, 2, 3])
def test_the_records_replay_to_the_certified_ceiling(n: int) -> None:
    certificate = committed_certificate(REVERSE_V1, n)
    records = committed_actions(REVERSE_V1, n)
    assert certificate is not None and records is not None
    feasible = {start.seed for start in certificate.starts if start.status == FEASIBLE}
    assert set(records) == feasible
    planner = planner_records(REVERSE_V1, n)
    assert planner is not None
    policy = load_policy("mpc-replay", REVERSE_V1, {"n_trailers": n}, seed=1000)
    results = rollout(policy, REVERSE_V1, 100, 1000, {"n_trailers": n})
    safe = {int(seed) for seed in results.seeds[results.safe]}
    # The oracle row replays the planner's records: each keeps its start safe, no other start is.
    assert safe == set(planner)
    # A witness's record (n = 3: the PPO agent's on the one start the planner left) too.
    kwargs = {"n_trailers": n}
    witnessed = feasible - set(planner)
    assert all(replays_to_success(REVERSE_V1, kwargs, seed, records[seed]) for seed in witnessed)
    assert len(witnessed) == (1 if n == 3 else 0)
    assert len(feasible) == round(100 * certificate.ceiling)


def test_the_four_trailer_records_replay_to_their_outcome() -> None:
    # Seeds 1000-1011 (fast): the record of every feasible start keeps it safe, open 1010 folds.
    certificate = committed_certificate(REVERSE_V1, 4)
    records = committed_actions(REVERSE_V1, 4)
    assert certificate is not None and records is not None
    statuses = {start.seed: start.status for start in certificate.starts}
    seeds = range(1000, 1012)
    feasible = {seed for seed in seeds if statuses[seed] == FEASIBLE}
    assert feasible == set(seeds) - {1010} and feasible == set(records) & set(seeds)
    policy = load_policy("mpc-replay", REVERSE_V1, {"n_trailers": 4}, seed=1000)
    results = rollout(policy, REVERSE_V1, len(seeds), 1000, {"n_trailers": 4})
    assert {int(seed) for seed in results.seeds[results.safe]} == feasible


def test_the_replay_refuses_other_physics() -> None:
    with pytest.raises(ValueError, match="default settings only"):
        load_policy("mpc-replay", REVERSE_V1, {"n_trailers": 2, "M": 1.2})
    with pytest.raises(ValueError, match="no committed action records"):
        load_policy("mpc-replay", REVERSE_V1, {"n_trailers": 9})


@pytest.mark.parametrize(
    ("arrays", "message"),
    [
        ({"seed_1": np.full((3, 1), np.nan)}, "outside"),
        ({"seed_1": np.full((3, 1), 2.0)}, "outside"),
        ({"start_1": np.zeros((3, 1))}, "unexpected entry"),
        ({"seed_1": np.zeros((3, 1), dtype=np.float32)}, "not a float64"),
        ({"seed_1": np.array([{"a": 1}], dtype=object)}, "not an action-record archive|pickle"),
    ],
)
def test_bad_records_are_refused(tmp_path: Path, arrays: dict, message: str) -> None:  # type: ignore[type-arg]
    path = actions_path(REVERSE_V1, 2, tmp_path)
    np.savez(path, **arrays)
    with pytest.raises(ValueError, match=message):
        committed_actions(REVERSE_V1, 2, tmp_path)


def test_records_round_trip_bit_for_bit(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    records = {1000: rng.uniform(-1, 1, (400, 1)), 1003: rng.uniform(-1, 1, (12, 1))}
    write_actions(records, actions_path(REVERSE_V1, 2, tmp_path))
    loaded = committed_actions(REVERSE_V1, 2, tmp_path)
    assert loaded is not None and sorted(loaded) == [1000, 1003]
    for seed, record in records.items():
        assert loaded[seed].tobytes() == record.tobytes()
    assert [path.name for path in tmp_path.iterdir()] == ["reverse_v1_n2_actions.npz"]


#: The committed randomised certificates (``--randomize mismatch20``): n -> feasible starts.
MISMATCH20 = {1: 98, 2: 100, 3: 98}


@pytest.mark.parametrize("n", sorted(MISMATCH20))
def test_the_randomised_records_replay_under_each_starts_drawn_physics(n: int) -> None:
    certificate = committed_certificate(REVERSE_V1, n, randomize="mismatch20")
    records = committed_actions(REVERSE_V1, n, randomize="mismatch20")
    assert certificate is not None and records is not None
    kwargs = {"n_trailers": n, "randomize": "mismatch20"}
    assert certificate.env_kwargs.kwargs() == kwargs
    feasible = {start.seed for start in certificate.starts if start.status == FEASIBLE}
    assert set(records) == feasible and len(feasible) == MISMATCH20[n]
    env = gym.make(REVERSE_V1, **kwargs)
    for start in certificate.starts:
        _, info = env.reset(seed=start.seed)
        assert start.params == info["params"]
    env.close()
    assert all(replays_to_success(REVERSE_V1, kwargs, seed, record)
               for seed, record in records.items())  # fmt: skip
