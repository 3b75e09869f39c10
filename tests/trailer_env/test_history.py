"""``history=k``: the last k observations and applied actions in the observation
(trailer_env.history), alike in the single env, the vector env and the SB3 adapter."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from trailer_env.mixed import pad_window_observations
from trailer_env.sb3 import ConvoySB3VecEnv

REVERSE = "trailer_env/Reverse-v1"


def frames(obs: np.ndarray, k: int, action_dim: int = 1) -> tuple[np.ndarray, list[tuple]]:
    """The current observation and the k past (observation, action) frames of a window."""
    d = (obs.shape[-1] - k * action_dim) // (k + 1)
    past = []
    for j in range(k):
        start = d + j * (d + action_dim)
        past.append((obs[start : start + d], obs[start + d : start + d + action_dim]))
    return obs[:d], past


def test_the_window_holds_the_last_observations_and_the_clipped_actions() -> None:
    k = 3
    env = gym.make(REVERSE, n_trailers=2, randomize="mismatch20", history=k)
    plain = gym.make(REVERSE, n_trailers=2, randomize="mismatch20")
    obs, _ = env.reset(seed=4)
    seen = [plain.reset(seed=4)[0]]
    assert obs.shape == env.observation_space.shape == (8 + k * 9,)
    current, past = frames(obs, k)
    np.testing.assert_array_equal(current, seen[0])
    for observation, action in past:  # a start: the start at rest before it
        np.testing.assert_array_equal(observation, seen[0])
        assert action.tolist() == [0.0]
    actions = [0.4, 3.0, -0.7, -2.0]
    for action in actions:
        obs, *_ = env.step(np.array([action], np.float32))
        seen.append(plain.step(np.array([action], np.float32))[0])
    current, past = frames(obs, k)
    np.testing.assert_array_equal(current, seen[-1])
    for j, (observation, action) in enumerate(past, start=1):
        np.testing.assert_array_equal(observation, seen[-1 - j])
        assert action[0] == np.float32(np.clip(actions[-j], -1.0, 1.0))
    low, high = env.observation_space.low, env.observation_space.high
    assert low[8 + 8] == -1.0 and high[8 + 8] == 1.0  # the first past action's bounds
    np.testing.assert_array_equal(low[8:16], plain.observation_space.low)


def test_set_state_and_reset_start_the_window_again() -> None:
    env = gym.make(REVERSE, n_trailers=1, history=2)
    env.reset(seed=0)
    for _ in range(3):
        env.step(np.array([1.0], np.float32))
    obs, _ = env.reset(seed=1)
    current, past = frames(obs, 2)
    assert all(np.array_equal(observation, current) for observation, _ in past)
    assert all(action[0] == 0.0 for _, action in past)
    env.step(np.array([0.5], np.float32))
    env.unwrapped.set_state([1.0, 0.0, 0.1])
    obs = env.unwrapped.core.obs[0]
    current, past = frames(obs, 2)
    assert all(np.array_equal(observation, current) for observation, _ in past)
    assert all(action[0] == 0.0 for _, action in past)


@pytest.mark.parametrize("autoreset_mode", ["next_step", "same_step"])
def test_a_vector_row_replays_the_single_env_across_episode_ends(autoreset_mode: str) -> None:
    count, seed, k = 3, 30, 4
    envs = gym.make_vec(
        REVERSE,
        num_envs=count,
        vectorization_mode="vector_entry_point",
        n_trailers=2,
        randomize="mismatch20",
        history=k,
        max_episode_steps=25,
        autoreset_mode=autoreset_mode,
    )
    singles = [
        gym.make(REVERSE, n_trailers=2, randomize="mismatch20", history=k, max_episode_steps=25)
        for _ in range(count)
    ]
    obs, _ = envs.reset(seed=seed)
    single_obs = [env.reset(seed=seed + i)[0] for i, env in enumerate(singles)]
    rng = np.random.default_rng(0)
    ended = np.zeros(count, dtype=bool)
    episodes = 0
    for _ in range(60):
        np.testing.assert_array_equal(obs, np.stack(single_obs))
        actions = rng.uniform(-1.5, 1.5, (count, 1)).astype(np.float32)
        obs, _, terminated, truncated, infos = envs.step(actions)
        for i, env in enumerate(singles):
            if autoreset_mode == "next_step" and ended[i]:
                single_obs[i] = env.reset()[0]
                continue
            single_obs[i], _, done, cut, _ = env.step(actions[i])
            if autoreset_mode == "same_step" and (done or cut):
                np.testing.assert_array_equal(infos["final_obs"][i], single_obs[i])
                single_obs[i] = env.reset()[0]
        ended = terminated | truncated
        episodes += int(ended.sum())
    assert episodes >= count  # every row crossed an episode's end


def test_the_sb3_adapter_gives_the_vector_envs_window() -> None:
    adapter = ConvoySB3VecEnv(REVERSE, num_envs=4, n_trailers=3, history=5)
    adapter.seed(9)
    first = adapter.reset()
    envs = gym.make_vec(
        REVERSE, num_envs=4, vectorization_mode="vector_entry_point", n_trailers=3, history=5
    )
    vector_obs, _ = envs.reset(seed=9)
    np.testing.assert_array_equal(first, vector_obs)
    actions = np.linspace(-1.0, 1.0, 4, dtype=np.float32)[:, None]
    for _ in range(5):
        obs, *_ = adapter.step(actions)
        vector_obs, *_ = envs.step(actions)
    np.testing.assert_array_equal(obs, vector_obs)
    assert obs.shape == (4, 10 + 5 * 11)


def test_a_range_of_counts_pads_every_frame() -> None:
    """Row i of ``trailer_draw="row"`` is the env of ``n = low + i`` seeded ``s + i``: its
    window is that env's, every frame padded."""
    k = 3
    mixed = gym.make_vec(
        REVERSE,
        num_envs=3,
        vectorization_mode="vector_entry_point",
        n_trailers=(1, 3),
        trailer_draw="row",
        history=k,
    )
    obs, _ = mixed.reset(seed=5)
    singles = [gym.make(REVERSE, n_trailers=n, history=k) for n in (1, 2, 3)]
    single_obs = [env.reset(seed=5 + i)[0] for i, env in enumerate(singles)]
    actions = np.array([[0.3], [-0.2], [0.9]], np.float32)
    for _ in range(4):
        obs, *_ = mixed.step(actions)
        single_obs = [env.step(actions[i])[0] for i, env in enumerate(singles)]
    for i, n in enumerate((1, 2, 3)):
        padded = pad_window_observations(single_obs[i], n, 3, k, 1)[0]
        np.testing.assert_array_equal(obs[i], padded)


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"history": -1}, ValueError, "history"),
        ({"history": 65}, ValueError, "history"),
        ({"history": 1.5}, ValueError, "history must be an integer"),
        ({"history": "8"}, TypeError, "history"),
        ({"history": True}, TypeError, "history"),
        ({"history": 2, "observation": "trailers"}, ValueError, "needs observation='flat'"),
    ],
)
def test_bad_windows_are_refused(kwargs: dict[str, object], error: type, message: str) -> None:
    with pytest.raises(error, match=message):
        gym.make(REVERSE, n_trailers=2, **kwargs)


def test_no_history_changes_nothing() -> None:
    plain = gym.make(REVERSE, n_trailers=2)
    zero = gym.make(REVERSE, n_trailers=2, history=0)
    assert plain.observation_space == zero.observation_space
    np.testing.assert_array_equal(plain.reset(seed=3)[0], zero.reset(seed=3)[0])
    assert type(zero.unwrapped.core) is type(plain.unwrapped.core)


def test_the_mirror_signs_cover_every_frame() -> None:
    env = gym.make(REVERSE, n_trailers=2, history=2)
    plain = gym.make(REVERSE, n_trailers=2)
    signs, action_signs = env.unwrapped.core.mirror_signs()
    plain_signs, plain_action = plain.unwrapped.core.mirror_signs()
    np.testing.assert_array_equal(
        signs, np.concatenate([plain_signs, *([plain_signs, plain_action] * 2)])
    )
    np.testing.assert_array_equal(action_signs, plain_action)
