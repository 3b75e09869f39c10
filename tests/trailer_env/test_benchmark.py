"""The benchmark protocol: one call scores any policy on the tables' episodes."""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import numpy as np
import pytest

from trailer_env.benchmark import (
    EPISODES,
    PROTOCOL,
    TASKS,
    TEST_SEED,
    per_observation,
    rollout,
    score,
    summarize,
)
from trailer_env.controllers import LQRController
from trailer_env.settings import settings_from_kwargs

REVERSE_V1 = "trailer_env/Reverse-v1"


def lqr(n_trailers: int) -> LQRController:
    return LQRController(settings_from_kwargs(n_trailers=n_trailers))


def test_the_protocol_scores_the_lqr_as_the_tables_do(tmp_path: Path) -> None:
    result = score(lqr(2), REVERSE_V1, 2, name="lqr", out=tmp_path / "score")
    document = json.loads((tmp_path / "score" / "score.json").read_text())
    assert document["protocol"] == PROTOCOL == "trailer_env-benchmark/1"
    assert document["on_protocol"] is True and (REVERSE_V1, 2) in TASKS
    assert document["seeds"] == [TEST_SEED, TEST_SEED + EPISODES - 1] == [1000, 1099]
    assert document["headline_metric"] == "safe_rate"
    # The README's LQR row on Reverse-v1, n = 2: 91 % safe on the test seeds.
    assert document["metrics"]["safe_rate"] == 0.91
    assert document["metrics"] == result.summary
    low, high = document["headline_ci"]
    assert low < 0.91 < high and high - low < 0.15
    table = (tmp_path / "score" / "score.md").read_text()
    assert table == result.markdown and "| lqr | 91% [" in table


def test_a_function_of_one_observation_scores_the_same_as_its_batch() -> None:
    controller = lqr(1)
    batched = rollout(controller, REVERSE_V1, 12, 1000, {"n_trailers": 1})
    single = rollout(
        per_observation(lambda obs: controller(obs)[0]), REVERSE_V1, 12, 1000, {"n_trailers": 1}
    )
    assert summarize(batched) == summarize(single)
    np.testing.assert_array_equal(batched.returns, single.returns)


def test_the_zero_action_folds_every_reversing_convoy() -> None:
    result = score(lambda obs: np.zeros((len(obs), 1)), REVERSE_V1, 2, episodes=20)
    assert result.summary["safe_rate"] == 0.0 and result.document["on_protocol"] is False
    assert result.summary["episodes"] == 20 and result.summary["jackknife_rate"] > 0.5


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"episodes": 0}, ValueError, "episodes must be in 1..100000"),
        ({"episodes": 10**7}, ValueError, "episodes must be in 1..100000"),
        ({"episodes": 2.5}, TypeError, "episodes must be an integer"),
        ({"episodes": True}, TypeError, "episodes must be an integer"),
        ({"seed": -1}, ValueError, "seed must be in"),
        ({"seed": 2**64}, ValueError, "seed must be in"),
    ],
)
def test_bad_counts_and_seeds_are_refused_before_any_episode(kwargs, error, message) -> None:  # type: ignore[no-untyped-def]
    def never(obs: np.ndarray) -> np.ndarray:
        raise AssertionError("no episode may run")

    with pytest.raises(error, match=message):
        score(never, REVERSE_V1, 2, **kwargs)


def test_an_existing_score_is_kept_unless_overwrite(tmp_path: Path) -> None:
    zero = lambda obs: np.zeros((len(obs), 1))  # noqa: E731
    score(zero, REVERSE_V1, 1, episodes=2, out=tmp_path)
    before = (tmp_path / "score.json").read_bytes()
    with pytest.raises(ValueError, match=r"score\.json exists; pass overwrite=True"):
        score(zero, REVERSE_V1, 1, episodes=3, out=tmp_path)
    assert (tmp_path / "score.json").read_bytes() == before
    score(zero, REVERSE_V1, 1, episodes=3, out=tmp_path, overwrite=True)
    assert json.loads((tmp_path / "score.json").read_text())["episodes"] == 3
    assert sorted(path.name for path in tmp_path.iterdir()) == ["score.json", "score.md"]
    with pytest.raises(ValueError, match="unknown environment"):
        score(zero, "trailer_env/Nope-v0", 1)


# ----------------------------------------------------------- issue 27 item 4: score()
def _never(obs: np.ndarray) -> np.ndarray:
    raise AssertionError("no episode may run")


def _zero(obs: np.ndarray) -> np.ndarray:
    return np.zeros((len(obs), 1))


def test_numpy_integers_are_integers_in_the_json(tmp_path: Path) -> None:
    out = tmp_path / "np"
    result = score(_zero, REVERSE_V1, np.int64(1), episodes=np.int32(2), seed=np.uint16(5), out=out)
    document = json.loads((out / "score.json").read_text())
    assert (document["n_trailers"], document["episodes"], document["seeds"]) == (1, 2, [5, 6])
    assert type(result.document["n_trailers"]) is int and document["on_protocol"] is False
    assert json.loads(json.dumps(result.document)) == document


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"n_trailers": True}, TypeError, "n_trailers must be an integer, got bool"),
        ({"n_trailers": 2.0}, TypeError, "n_trailers must be an integer, got float"),
        ({"n_trailers": np.float64(2)}, TypeError, "n_trailers must be an integer, got float64"),
        ({"seed": np.bool_(True)}, TypeError, "seed must be an integer, got bool"),
        ({"episodes": np.float32(3)}, TypeError, "episodes must be an integer, got float32"),
        ({"overwrite": "no"}, TypeError, "overwrite must be a bool, got str 'no'"),
        ({"overwrite": 1}, TypeError, "overwrite must be a bool, got int 1"),
        ({"goal_conditioned": None}, TypeError, "goal_conditioned must be a bool"),
        ({"name": 7}, TypeError, "name must be a str, got int 7"),
        ({"out": ""}, ValueError, "out='' names no folder; pass '.'"),
        ({"out": 5}, TypeError, r"out must be a path \(str or os.PathLike\), got int"),
    ],
)
def test_score_refuses_bad_types_before_any_episode(kwargs, error, message) -> None:  # type: ignore[no-untyped-def]
    arguments = {"n_trailers": 2, **kwargs}
    with pytest.raises(error, match=message):
        score(_never, REVERSE_V1, **arguments)


def test_a_refused_target_writes_nothing(tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "score.md").symlink_to(tmp_path / "nowhere.md")  # dangling
    with pytest.raises(ValueError, match=r"score\.md is a symbolic link; refusing"):
        score(_never, REVERSE_V1, 1, episodes=2, out=out, overwrite=True)
    assert sorted(path.name for path in out.iterdir()) == ["score.md"]
    assert not (tmp_path / "nowhere.md").exists()
    (out / "score.md").unlink()
    (out / "score.json").mkdir()
    with pytest.raises(ValueError, match=r"score\.json is a folder"):
        score(_never, REVERSE_V1, 1, episodes=2, out=out, overwrite=True)
    (tmp_path / "a_file").write_text("")
    with pytest.raises(ValueError, match="not a folder"):
        score(_never, REVERSE_V1, 1, episodes=2, out=tmp_path / "a_file")


@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_score_files_honour_the_umask(tmp_path: Path, umask: int) -> None:
    previous = os.umask(umask)
    try:
        score(_zero, REVERSE_V1, 1, episodes=1, out=tmp_path)
    finally:
        os.umask(previous)
    for file in ("score.json", "score.md"):
        assert stat.S_IMODE((tmp_path / file).stat().st_mode) == 0o666 & ~umask
