"""The state contract: ``set_state`` starts an episode for the wrappers too, takes what
``get_state`` returns on every scene and with a range of trailer counts, and a start
replay serves one batch."""

from __future__ import annotations

import gc
import pickle
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.wrappers import TimeLimit

from trailer_env.registry import ENVIRONMENTS
from trailer_env.sb3 import ConvoySB3VecEnv
from trailer_env.start_replay import StartReplay

HEADING = "trailer_env/Heading-v0"


def _steps_to_end(env: gym.Env, limit: int = 1000) -> tuple[int, bool]:
    """Zero-action steps until the episode ends, and whether the time limit ended it."""
    zero = np.zeros(1, dtype=np.float32)  # every scene's action: one number
    for count in range(1, limit + 1):
        _, _, terminated, truncated, _ = env.step(zero)
        if terminated or truncated:
            return count, bool(truncated and not terminated)
    return limit, False


def test_set_state_gives_the_episode_its_whole_time_limit() -> None:
    env = gym.make(HEADING)
    assert env.spec is not None and env.spec.max_episode_steps == 300
    env.reset(seed=0)
    start = env.unwrapped.get_state()  # type: ignore[attr-defined]
    zero = np.zeros(1, dtype=np.float32)
    for _ in range(150):
        env.step(zero)
    env.unwrapped.set_state(start)  # type: ignore[attr-defined]
    assert _steps_to_end(env) == (300, True)
    # the same as a reset to that state through the wrappers
    env.reset(options={"state": start["z"], "target_heading": start["target_heading"]})
    assert _steps_to_end(env) == (300, True)


def test_set_state_restarts_a_time_limit_of_ones_own_and_after_a_truncation() -> None:
    env: TimeLimit[Any, Any] = TimeLimit(gym.make(HEADING).unwrapped, max_episode_steps=20)
    env.reset(seed=1)
    start = env.unwrapped.get_state()  # type: ignore[attr-defined]
    assert _steps_to_end(env) == (20, True)
    env.unwrapped.set_state(start)  # type: ignore[attr-defined]
    assert _steps_to_end(env) == (20, True)
    for _ in range(7):
        env.step(np.zeros(1, dtype=np.float32))
    env.unwrapped.set_state(**start)  # type: ignore[attr-defined]
    assert _steps_to_end(env) == (20, True)


@pytest.mark.parametrize("env_id", sorted(ENVIRONMENTS))
def test_set_state_takes_what_get_state_returns(env_id: str) -> None:
    env = gym.make(env_id)
    env.reset(seed=3)
    for _ in range(4):
        obs, *_ = env.step(np.full(1, 0.2, dtype=np.float32))
    state = env.unwrapped.get_state()  # type: ignore[attr-defined]
    other = gym.make(env_id)
    other.reset(seed=11)
    np.testing.assert_array_equal(other.unwrapped.set_state(state), obs)  # type: ignore[attr-defined]
    again = other.unwrapped.get_state()  # type: ignore[attr-defined]
    assert again.keys() == state.keys()
    for key, value in state.items():
        np.testing.assert_array_equal(again[key], value)
    # the same env, set back to its own state
    np.testing.assert_array_equal(env.unwrapped.set_state(state), obs)  # type: ignore[attr-defined]


def test_a_state_dict_is_given_alone_and_whole() -> None:
    env = gym.make("trailer_env/Reverse-v1")
    env.reset(seed=0)
    state = env.unwrapped.get_state()  # type: ignore[attr-defined]
    before = env.unwrapped.get_state()  # type: ignore[attr-defined]
    with pytest.raises(TypeError, match="alone"):
        env.unwrapped.set_state(state, s=0.1)  # type: ignore[attr-defined]
    with pytest.raises(ValueError, match="'z'"):
        env.unwrapped.set_state({"s": 0.0})  # type: ignore[attr-defined]
    with pytest.raises(ValueError, match="unknown task value"):
        env.unwrapped.set_state({**state, "target": [0.0, 0.0, 0.0]})  # type: ignore[attr-defined]
    np.testing.assert_array_equal(env.unwrapped.get_state()["z"], before["z"])  # type: ignore[attr-defined]


@pytest.mark.parametrize("env_id", ["trailer_env/Reverse-v1", HEADING, "trailer_env/Dock-v0"])
def test_a_range_of_counts_reads_and_writes_the_running_episode(env_id: str) -> None:
    env = gym.make(env_id, n_trailers=(1, 3))
    counts = set()
    for seed in range(6):
        _, info = env.reset(seed=seed)
        n = info["n_trailers"]
        counts.add(n)
        state = env.unwrapped.get_state()  # type: ignore[attr-defined]
        z = env.unwrapped.state  # type: ignore[attr-defined]
        pose = 3 if env_id != "trailer_env/Reverse-v1" else 0
        assert z.shape == state["z"].shape == (2 + n + pose,)
        np.testing.assert_array_equal(z, state["z"])
    assert len(counts) > 1  # the seeds drew more than one count
    # round trip into another env of the range, whichever count its episode drew
    env.reset(seed=0)
    action = np.full(1, 0.3, dtype=np.float32)
    for _ in range(3):
        env.step(action)
    state = env.unwrapped.get_state()  # type: ignore[attr-defined]
    other = gym.make(env_id, n_trailers=(1, 3))
    other.reset(seed=5)
    first = other.unwrapped.set_state(state)  # type: ignore[attr-defined]
    np.testing.assert_array_equal(first, env.unwrapped.set_state(state))  # type: ignore[attr-defined]
    for _ in range(5):
        a, ra, *_, info_a = env.step(action)
        b, rb, *_, info_b = other.step(action)
        np.testing.assert_array_equal(a, b)
        assert ra == rb and info_a["n_trailers"] == info_b["n_trailers"] == state["z"].size - 2 - (
            3 if env_id != "trailer_env/Reverse-v1" else 0
        )
    with pytest.raises(ValueError, match=r"a state of n in 1\.\.3 trailers"):
        other.unwrapped.set_state(np.zeros(40))  # type: ignore[attr-defined]


def test_the_vector_env_refuses_one_state_width_for_a_range() -> None:
    envs = gym.make_vec(
        "trailer_env/Reverse-v1",
        num_envs=2,
        vectorization_mode="vector_entry_point",
        n_trailers=(1, 2),
    )
    envs.reset(seed=0)
    with pytest.raises(ValueError, match="one number of trailers"):
        envs.reset(options={"state": np.zeros((2, 4))})


def test_a_start_replay_serves_one_batch() -> None:
    first = ConvoySB3VecEnv("trailer_env/Dock-v0", num_envs=4, n_trailers=2)
    replay = StartReplay(0.5, seed=0)
    first.set_start_replay(replay)
    first.reset()
    other = ConvoySB3VecEnv("trailer_env/Dock-v0", num_envs=4, n_trailers=2)
    with pytest.raises(ValueError, match="serves another batch"):
        other.set_start_replay(replay)
    assert other.start_replay is None
    bigger = ConvoySB3VecEnv("trailer_env/Dock-v0", num_envs=8, n_trailers=2)
    del first
    gc.collect()
    with pytest.raises(ValueError, match=r"4 environments, .* not of DockCore with 8"):
        bigger.set_start_replay(replay)
    assert bigger.start_replay is None
    other.set_start_replay(replay)  # the first batch is gone: one of its layout takes over
    other.reset()
    for _ in range(3):
        other.step(np.zeros((4, 1), dtype=np.float32))
    assert replay.replaying.shape == (4,)
    copy = pickle.loads(pickle.dumps(other))
    copy.step(np.zeros((4, 1), dtype=np.float32))
    assert copy.start_replay is not None and copy.start_replay.replaying.shape == (4,)


def test_a_start_replay_set_aside_may_serve_another_batch() -> None:
    first = ConvoySB3VecEnv("trailer_env/Dock-v0", num_envs=4, n_trailers=2)
    replay = StartReplay(0.5, seed=0)
    first.set_start_replay(replay)
    first.reset()
    first.set_start_replay(None)  # the first batch lives on, without the replay
    other = ConvoySB3VecEnv("trailer_env/Dock-v0", num_envs=4, n_trailers=2)
    other.set_start_replay(replay)
    other.reset()
    other.step(np.zeros((4, 1), dtype=np.float32))
    assert other.start_replay is replay and replay.replaying.shape == (4,)
    with pytest.raises(ValueError, match="serves another batch"):
        first.set_start_replay(replay)
