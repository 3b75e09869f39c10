"""``get_state`` / ``state``: reading the state that ``set_state`` writes."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import trailer_env  # noqa: F401  (registers the ids)


@pytest.mark.parametrize(
    ("env_id", "keywords", "task_keys"),
    [
        ("trailer_env/Reverse-v1", {}, set()),
        ("trailer_env/Coast-v0", {"render_mode": "rgb_array"}, set()),
        ("trailer_env/Heading-v0", {}, {"target_heading"}),
        ("trailer_env/Dock-v0", {"action_mode": "accel"}, {"target"}),
    ],
)
def test_get_state_round_trips_through_set_state(
    env_id: str, keywords: dict[str, str], task_keys: set[str]
) -> None:
    env = gym.make(env_id, **keywords)
    env.reset(seed=3)
    for _ in range(5):
        obs, *_ = env.step(np.full(env.action_space.shape, 0.3, dtype=np.float32))
    state = env.unwrapped.get_state()
    assert set(state) == {"z", "s", "s_dot", *task_keys}
    np.testing.assert_array_equal(state["z"], env.unwrapped.state)
    other = gym.make(env_id, **keywords)
    other.reset(seed=9)  # another start and, for the goal scenes, another target
    np.testing.assert_array_equal(other.unwrapped.set_state(**state), obs)
    again = other.unwrapped.get_state()
    assert again.keys() == state.keys()
    for key, value in state.items():
        np.testing.assert_array_equal(again[key], value)


def test_get_state_returns_copies() -> None:
    env = gym.make("trailer_env/Dock-v0")
    env.reset(seed=0)
    state = env.unwrapped.get_state()
    state["z"][0] = 99.0
    state["target"][0] = 99.0
    fresh = env.unwrapped.get_state()
    assert fresh["z"][0] != 99.0
    assert fresh["target"][0] != 99.0
    view = env.unwrapped.state
    view[0] = 99.0
    assert env.unwrapped.state[0] != 99.0


def test_get_state_before_reset_is_refused() -> None:
    env = gym.make("trailer_env/Reverse-v1")
    with pytest.raises(gym.error.ResetNeeded, match="reset"):
        env.unwrapped.get_state()
