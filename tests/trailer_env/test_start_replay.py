"""Start replay (trailer_env.start_replay): recorded starts (drawn physics included)
replay to the bit, failed starts come back, successful ones do not, the scene's draws
are unchanged, and refusals."""

from __future__ import annotations

import numpy as np
import pytest

from trailer_env.sb3 import ConvoySB3VecEnv
from trailer_env.start_replay import StartReplay

DOCK = "trailer_env/Dock-v0"
V1 = "trailer_env/Reverse-v1"


def _actions(count: int, size: int) -> np.ndarray:
    return np.random.default_rng(5).uniform(-1, 1, (count, size, 1)).astype(np.float32)


def _rollout(venv: ConvoySB3VecEnv, actions: np.ndarray) -> np.ndarray:
    return np.stack([venv.step(batch)[0] for batch in actions])


@pytest.mark.parametrize("env_id", [DOCK, V1])
def test_a_restarted_start_replays_its_episode_to_the_bit(env_id: str) -> None:
    venv = ConvoySB3VecEnv(env_id, num_envs=4, n_trailers=2, max_episode_steps=1000)
    venv.seed(3)
    first = venv.reset().copy()
    rows = np.array([0, 2])
    record = venv.core.start_records(rows)
    actions = _actions(12, 4)
    before = _rollout(venv, actions)
    venv.core.restart(rows, record)
    np.testing.assert_array_equal(venv.core.obs[rows], first[rows])
    after = _rollout(venv, actions)
    np.testing.assert_array_equal(after[:, rows], before[:, rows])
    assert not np.array_equal(after[:, 1], before[:, 1])  # the others went on


@pytest.mark.parametrize("observe_params", [False, True])
def test_a_restarted_start_replays_its_drawn_physics_to_the_bit(observe_params: bool) -> None:
    venv = ConvoySB3VecEnv(
        V1,
        num_envs=4,
        n_trailers=2,
        randomize="mismatch20",
        observe_params=observe_params,
        max_episode_steps=1000,
    )
    venv.seed(3)
    first = venv.reset().copy()
    rows = np.array([1, 3])
    record = venv.core.start_records(rows)
    assert record.factors is not None and not np.all(record.factors[:, :5] == 1.0)
    values = venv.core.param_values[rows].copy()
    actions = _actions(12, 4)
    before = _rollout(venv, actions)
    venv.core.factors[rows] = 1.0  # a later draw would have changed them
    venv.core.restart(rows, record)
    np.testing.assert_array_equal(venv.core.param_values[rows], values)
    np.testing.assert_array_equal(venv.core.obs[rows], first[rows])
    after = _rollout(venv, actions)
    np.testing.assert_array_equal(after[:, rows], before[:, rows])


def test_a_record_with_or_without_drawn_physics_fits_only_its_kind_of_batch() -> None:
    drawn = ConvoySB3VecEnv(V1, num_envs=2, n_trailers=1, randomize="mismatch20")
    fixed = ConvoySB3VecEnv(V1, num_envs=2, n_trailers=1)
    for venv in (drawn, fixed):
        venv.seed(0)
        venv.reset()
    rows = np.array([0])
    for source, target in ((drawn, fixed), (fixed, drawn)):
        z = target.core.z.copy()
        with pytest.raises(ValueError, match="does not fit 1 rows"):
            target.core.restart(rows, source.core.start_records(rows))
        np.testing.assert_array_equal(target.core.z, z)


def test_replayed_episodes_meet_the_convoy_that_failed() -> None:
    venv = ConvoySB3VecEnv(V1, num_envs=32, n_trailers=1, randomize="mismatch20")
    replay = StartReplay(0.5, seed=0)
    venv.set_start_replay(replay)
    venv.seed(0)
    venv.reset()
    zero = np.zeros((32, 1), dtype=np.float32)
    core = venv.core
    failed: list[np.ndarray] = []  # state row and drawn factors of each failed episode's start
    running = np.concatenate([core.z, core.factors], axis=1)  # each row's episode's start
    replays = 0
    for _ in range(300):  # the zero action folds every episode
        dones = venv.step(zero)[2]
        failed.extend(running[dones])
        begun = np.concatenate([core.z, core.factors], axis=1)
        for i in np.flatnonzero(dones & replay.replaying).tolist():
            assert any(np.array_equal(begun[i], start) for start in failed)
            replays += 1
        running[dones] = begun[dones]
    assert replays > 50


def test_restart_refuses_a_record_that_does_not_fit() -> None:
    venv = ConvoySB3VecEnv(DOCK, num_envs=4, n_trailers=2)
    venv.reset()
    record = venv.core.start_records(np.array([0, 1]))
    z = venv.core.z.copy()
    with pytest.raises(ValueError, match="does not fit 3 rows"):
        venv.core.restart(np.array([0, 1, 2]), record)
    np.testing.assert_array_equal(venv.core.z, z)


def test_every_episode_that_fails_is_kept_and_replayed_ones_come_from_it() -> None:
    venv = ConvoySB3VecEnv(V1, num_envs=64, n_trailers=2)
    plain = ConvoySB3VecEnv(V1, num_envs=64, n_trailers=2)
    replay = StartReplay(0.5, capacity=1000, seed=1)
    venv.set_start_replay(replay)
    for env in (venv, plain):
        env.seed(0)
    first = venv.reset().copy()
    np.testing.assert_array_equal(first, plain.reset())
    seen = list(first)  # every start begun so far
    zero = np.zeros((64, 1), dtype=np.float32)
    diverged = np.zeros(64, dtype=bool)  # rows that replayed: their episodes differ since
    failures = replayed = 0
    for _ in range(150):  # the zero action folds every episode (test_reverse_v1)
        obs, _, dones, _ = venv.step(zero)
        plain_obs, _, plain_dones, _ = plain.step(zero)
        np.testing.assert_array_equal(dones[~diverged], plain_dones[~diverged])
        for i in np.flatnonzero(dones).tolist():
            failures += 1
            if not diverged[i] and np.array_equal(obs[i], plain_obs[i]):
                seen.append(obs[i].copy())  # the scene's own next start, as without replay
                continue
            if any(np.array_equal(obs[i], start) for start in seen):
                replayed += 1  # a start an episode began from before
                diverged[i] = True
            else:
                assert diverged[i]  # a diverged row's own draw
                seen.append(obs[i].copy())
    # Every failure went into the buffer; each replay took one out.
    assert replay.size == failures - replayed
    assert 0.3 < replayed / failures < 0.6


def test_successes_are_not_kept_and_the_buffer_stays_within_capacity() -> None:
    # Reverse-v1's episodes that outlast the time limit are successes.
    venv = ConvoySB3VecEnv(V1, num_envs=8, n_trailers=1, max_episode_steps=3)
    replay = StartReplay(0.5, capacity=3, seed=0)
    venv.set_start_replay(replay)
    venv.seed(0)
    venv.reset()
    for _ in range(9):
        venv.step(np.zeros((8, 1), dtype=np.float32))
    assert replay.size == 0 and replay.replayed == 0
    folding = ConvoySB3VecEnv(V1, num_envs=8, n_trailers=1)
    small = StartReplay(0.5, capacity=3, seed=0)
    folding.set_start_replay(small)
    folding.seed(0)
    folding.reset()
    for _ in range(400):
        folding.step(np.full((8, 1), 1.0, dtype=np.float32))
        assert small.size <= 3
    assert small.replayed > 0 and small.replayed_successes == 0


@pytest.mark.parametrize(
    ("kwargs", "error", "words"),
    [
        ({"fraction": 0.0}, ValueError, "fraction"),
        ({"fraction": 1.0}, ValueError, "fraction"),
        ({"fraction": "half"}, TypeError, "fraction"),
        ({"fraction": 0.5, "capacity": 0}, ValueError, "capacity"),
        ({"fraction": 0.5, "seed": -1}, ValueError, "seed"),
        ({"fraction": 0.5, "max_replays": 0}, ValueError, "max_replays"),
    ],
)
def test_bad_replay_settings_are_refused(kwargs: dict, error: type, words: str) -> None:
    with pytest.raises(error, match=words):
        StartReplay(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "error", "words"),
    [
        ({"n_trailers": [1, 2]}, ValueError, "one count of trailers"),
    ],
)
def test_batches_whose_starts_cannot_be_recorded_refuse_a_replay(
    kwargs: dict, error: type, words: str
) -> None:
    venv = ConvoySB3VecEnv(V1, num_envs=4, **kwargs)
    with pytest.raises(error, match=words):
        venv.set_start_replay(StartReplay(0.5))
    assert venv.start_replay is None
    with pytest.raises(TypeError, match="StartReplay or None"):
        ConvoySB3VecEnv(V1, num_envs=4).set_start_replay(0.5)  # type: ignore[arg-type]


@pytest.mark.parametrize("max_replays", [None, 1, 2])
def test_a_start_leaves_the_buffer_after_max_replays_failed(max_replays: int | None) -> None:
    venv = ConvoySB3VecEnv(V1, num_envs=32, n_trailers=1)
    replay = StartReplay(0.5, seed=0, max_replays=max_replays)
    venv.set_start_replay(replay)
    venv.seed(0)
    venv.reset()
    zero = np.zeros((32, 1), dtype=np.float32)
    fresh_failures = 0
    for _ in range(600):  # the zero action folds every episode
        replaying = replay.replaying  # the running episodes' (a new array each read)
        dones = venv.step(zero)[2]
        fresh_failures += int(np.count_nonzero(dones & ~replaying))
    counts = replay._stored_replays[: replay.size]
    assert replay.replayed > 0 and replay.replayed_successes == 0
    if max_replays is None:
        assert counts.max() >= 2  # failed starts keep coming back
    else:
        # Each start is stored with the replays it has failed, never max_replays of them,
        # so a fresh failure is replayed at most max_replays times.
        assert counts.max() < max_replays
        assert replay.replayed <= fresh_failures * max_replays
