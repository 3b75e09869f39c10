"""``observation="trailers"``: the flat observation rearranged, for every env and for mixed n."""

from __future__ import annotations

import time
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from tests.trailer_env.helpers import SCENE_IDS
from trailer_env.benchmark import rollout
from trailer_env.mixed import pad_observations
from trailer_env.observation import DEFAULT_MAX_TRAILERS, flat_observation, trailers_observation
from trailer_env.sb3 import ConvoySB3VecEnv
from trailer_env.vector import MAX_NUM_ENVS

REVERSE = "trailer_env/Reverse-v1"
KEYS = ("body", "mask", "trailers")


def rearranged(flat: np.ndarray, n: int, slots: int, padded: bool = False) -> dict[str, Any]:
    """The documented layout, index by index, written independently of the package."""
    flat = np.asarray(flat, dtype=np.float32)
    tail = flat.shape[-1] - 2 - (3 if padded else 2) * n
    trailers = np.zeros((*flat.shape[:-1], slots, 2), np.float32)
    mask = np.zeros((*flat.shape[:-1], slots), np.float32)
    for k in range(n):
        trailers[..., k, 0] = flat[..., 2 + k]
        trailers[..., k, 1] = flat[..., 2 + n + k]
        mask[..., k] = flat[..., 2 + 2 * n + tail + k] if padded else 1.0
    body = np.concatenate([flat[..., :2], flat[..., 2 + 2 * n : 2 + 2 * n + tail]], axis=-1)
    return {"body": body, "mask": mask, "trailers": trailers}


def assert_same(got: Any, expected: dict[str, Any]) -> None:
    assert isinstance(got, dict) and tuple(sorted(got)) == KEYS
    for key in KEYS:
        assert got[key].dtype == np.float32
        np.testing.assert_array_equal(got[key], expected[key], strict=True)


def actions(t: int, count: int = 1) -> np.ndarray:
    return np.sin(0.3 * t + np.arange(count, dtype=np.float32)).astype(np.float32)[:, None]


@pytest.mark.parametrize("env_id", SCENE_IDS)
def test_single_env_is_the_flat_observation_rearranged(env_id: str) -> None:
    kwargs: dict[str, Any] = {"n_trailers": 2}
    if env_id.endswith("Reverse-v0"):
        kwargs["observe_params"] = True  # the parameter features go to body, after the rest
    flat = gym.make(env_id, **kwargs)
    seq = gym.make(env_id, observation="trailers", max_trailers=5, **kwargs)
    expected, _ = flat.reset(seed=3)
    obs, _ = seq.reset(seed=3)
    assert_same(obs, rearranged(expected, 2, 5))
    assert obs in seq.observation_space
    width = expected.size - 4  # everything but the 2n hitch entries
    assert seq.observation_space["body"].shape == (width,)
    assert seq.observation_space["trailers"].shape == (5, 2)
    for t in range(25):
        expected, reward, done, cut, _ = flat.step(actions(t)[0])
        obs, got_reward, got_done, got_cut, _ = seq.step(actions(t)[0])
        assert_same(obs, rearranged(expected, 2, 5))
        assert obs in seq.observation_space
        assert (got_reward, got_done, got_cut) == (reward, done, cut)
        if done:
            break


def test_set_state_returns_the_rearranged_observation() -> None:
    flat = gym.make(REVERSE, n_trailers=3).unwrapped
    seq = gym.make(REVERSE, n_trailers=3, observation="trailers").unwrapped
    state = [-1.0, 0.02, 0.1, -0.2, 0.3]
    expected = flat.set_state(state, s=0.1)
    obs = seq.set_state(state, s=0.1)
    assert_same(obs, rearranged(expected, 3, DEFAULT_MAX_TRAILERS))
    np.testing.assert_array_equal(obs["trailers"][:3, 0], np.float32(np.sin([0.1, -0.2, 0.3])))


def test_check_env_passes_on_the_single_env() -> None:
    env = gym.make("trailer_env/Dock-v0", n_trailers=2, observation="trailers")
    with pytest.warns(UserWarning, match="infinity"):  # u, omega and Dock's offsets
        check_env(env.unwrapped)
    env = gym.make(REVERSE, n_trailers=(1, 3), observation="trailers", max_trailers=4)
    with pytest.warns(UserWarning, match="infinity"):
        check_env(env.unwrapped, skip_render_check=True)  # a range of counts renders nothing


@pytest.mark.parametrize("mode", ["next_step", "same_step"])
def test_vector_env_is_the_flat_one_rearranged(mode: str) -> None:
    common: dict[str, Any] = {
        "num_envs": 4,
        "vectorization_mode": "vector_entry_point",
        "autoreset_mode": mode,
        "n_trailers": 3,
    }
    flat = gym.make_vec("trailer_env/Reverse-v0", **common)
    seq = gym.make_vec("trailer_env/Reverse-v0", observation="trailers", **common)
    expected, _ = flat.reset(seed=10)
    obs, _ = seq.reset(seed=10)
    assert_same(obs, rearranged(expected, 3, DEFAULT_MAX_TRAILERS))
    assert obs in seq.observation_space
    ended = 0
    for t in range(120):
        expected, _, done, cut, info = flat.step(actions(t, 4))
        obs, _, got_done, got_cut, got_info = seq.step(actions(t, 4))
        assert_same(obs, rearranged(expected, 3, DEFAULT_MAX_TRAILERS))
        np.testing.assert_array_equal(got_done, done)
        np.testing.assert_array_equal(got_cut, cut)
        if mode == "same_step" and info.get("_final_obs", np.zeros(4, bool)).any():
            for i in np.flatnonzero(info["_final_obs"]):
                final = rearranged(info["final_obs"][i], 3, DEFAULT_MAX_TRAILERS)
                assert_same(got_info["final_obs"][i], final)
                ended += 1
    if mode == "same_step":
        assert ended > 0  # reversing under a sine wave folds within 120 steps


def test_mixed_n_is_the_padded_observation_rearranged_and_replays_each_n() -> None:
    count, seed = 6, 21
    common: dict[str, Any] = {
        "num_envs": count,
        "vectorization_mode": "vector_entry_point",
        "n_trailers": (1, 3),
    }
    flat = gym.make_vec(REVERSE, **common)
    seq = gym.make_vec(REVERSE, observation="trailers", max_trailers=6, **common)
    padded, info = flat.reset(seed=seed)
    obs, got_info = seq.reset(seed=seed)
    counts = info["n_trailers"]
    assert set(counts.tolist()) == {1, 2, 3}  # each count is in the batch
    np.testing.assert_array_equal(got_info["n_trailers"], counts)
    assert_same(obs, rearranged(padded, 3, 6, padded=True))
    # Row i, an episode of n trailers, is exactly the env made with n_trailers=n (same
    # max_trailers) whose generator drew the count first (trailer_env.mixed).
    singles = []
    for i, n in enumerate(counts.tolist()):
        rng = np.random.default_rng(seed + i)
        rng.random()
        single = gym.make(REVERSE, n_trailers=n, observation="trailers", max_trailers=6)
        single.unwrapped.np_random = rng
        first, _ = single.reset()
        assert_same({key: obs[key][i] for key in KEYS}, first)
        singles.append(single)
    for t in range(40):
        padded, _, done, _, _ = flat.step(actions(t, count))
        obs, _, got_done, _, _ = seq.step(actions(t, count))
        assert_same(obs, rearranged(padded, 3, 6, padded=True))
        for i, single in enumerate(singles):
            if single is None:
                continue
            expected, _, ended, _, _ = single.step(actions(t, count)[i])
            assert_same({key: obs[key][i] for key in KEYS}, expected)
            if ended:
                singles[i] = None  # the batch starts another episode (another count)
        np.testing.assert_array_equal(got_done, done)


def test_sb3_adapter_is_the_flat_one_rearranged() -> None:
    flat = ConvoySB3VecEnv(REVERSE, num_envs=5, n_trailers=(1, 3))
    seq = ConvoySB3VecEnv(REVERSE, num_envs=5, n_trailers=(1, 3), observation="trailers")
    for venv in (flat, seq):
        venv.seed(4)
    assert_same(seq.reset(), rearranged(flat.reset(), 3, DEFAULT_MAX_TRAILERS, padded=True))
    terminals = 0
    for t in range(150):
        flat.step_async(actions(t, 5))
        seq.step_async(actions(t, 5))
        expected, rewards, dones, infos = flat.step_wait()
        obs, got_rewards, got_dones, got_infos = seq.step_wait()
        assert_same(obs, rearranged(expected, 3, DEFAULT_MAX_TRAILERS, padded=True))
        assert all({key: obs[key][i] for key in KEYS} in seq.observation_space for i in range(5))
        np.testing.assert_array_equal(got_rewards, rewards)
        np.testing.assert_array_equal(got_dones, dones)
        for i in np.flatnonzero(dones):
            last = rearranged(infos[i]["terminal_observation"], 3, 8, padded=True)
            assert_same(got_infos[i]["terminal_observation"], last)
            terminals += 1
    assert terminals > 0


@pytest.mark.parametrize("n", [0, 1, 3])
def test_the_padded_and_the_plain_layouts_give_one_dict(n: int, rng: np.random.Generator) -> None:
    flat = rng.normal(size=(7, 2 + 2 * n + 5)).astype(np.float32)
    plain = trailers_observation(flat, n, 4)
    assert_same(plain, rearranged(flat, n, 4))
    assert_same(trailers_observation(pad_observations(flat, n, 4), 4, 4, padded=True), plain)
    assert_same(trailers_observation(flat[2], n, 4), {key: plain[key][2] for key in KEYS})


def test_trailers_observation_refuses_what_does_not_fit() -> None:
    with pytest.raises(ValueError, match="do not fit max_trailers = 2"):
        trailers_observation(np.zeros(10), 3, 2)
    with pytest.raises(ValueError, match="width 5 hold fewer than 3 trailers"):
        trailers_observation(np.zeros(5), 3, 4)
    with pytest.raises(ValueError, match="1-D or 2-D"):
        trailers_observation(np.zeros((2, 2, 10)), 3, 4)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"observation": "grid"}, ValueError, r"observation must be one of \('flat', 'trailers'\)"),
        ({"observation": 1}, TypeError, "observation must be one of"),
        (
            {"observation": "trailers", "max_trailers": 2},
            ValueError,
            "max_trailers = 2 holds fewer trailers than n_trailers = 3",
        ),
        ({"observation": "trailers", "max_trailers": "8"}, TypeError, "max_trailers"),
        ({"observation": "trailers", "max_trailers": True}, TypeError, "max_trailers"),
        ({"observation": "trailers", "max_trailers": 257}, ValueError, "max_trailers"),
        ({"max_trailers": 8}, ValueError, "max_trailers applies to observation='trailers'"),
    ],
)
def test_bad_values_are_refused_naming_them(kwargs: dict, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        gym.make(REVERSE, n_trailers=3, **kwargs)
    with pytest.raises(error, match=match):
        gym.make_vec(
            REVERSE,
            num_envs=2,
            vectorization_mode="vector_entry_point",
            n_trailers=(1, 3),
            **kwargs,
        )
    with pytest.raises(error, match=match):
        ConvoySB3VecEnv(REVERSE, num_envs=2, n_trailers=3, **kwargs)


def test_the_default_slots_refuse_a_longer_convoy() -> None:
    with pytest.raises(ValueError, match=r"max_trailers = 8 \(the default\) .* n_trailers = 9"):
        gym.make(REVERSE, n_trailers=9, observation="trailers")
    env = gym.make(REVERSE, n_trailers=9, observation="trailers", max_trailers=9)
    assert env.observation_space["mask"].shape == (9,)


def test_a_refusal_comes_before_anything_is_allocated() -> None:
    # 2**24 environments of 200 trailers would need tens of GiB: refused first, at once.
    start = time.perf_counter()
    with pytest.raises(ValueError, match="observation must be one of"):
        ConvoySB3VecEnv(REVERSE, num_envs=MAX_NUM_ENVS, n_trailers=200, observation="seq")
    with pytest.raises(ValueError, match="max_trailers = 8"):
        ConvoySB3VecEnv(REVERSE, num_envs=MAX_NUM_ENVS, n_trailers=200, observation="trailers")
    assert time.perf_counter() - start < 5.0


def test_flat_is_the_default_and_unchanged() -> None:
    default = gym.make(REVERSE, n_trailers=2)
    named = gym.make(REVERSE, n_trailers=2, observation="flat")
    assert default.observation_space == named.observation_space
    assert isinstance(default.observation_space, gym.spaces.Box)
    first, _ = default.reset(seed=0)
    second, _ = named.reset(seed=0)
    np.testing.assert_array_equal(first, second, strict=True)


def test_the_scoring_rollout_refuses_the_dict_observation() -> None:
    with pytest.raises(ValueError, match="rollout scores policies on the flat observation"):
        rollout(lambda obs: np.zeros((2, 1)), REVERSE, 2, 1000, {"observation": "trailers"})
    with pytest.raises(TypeError, match="DAgger reads the flat observation"):
        flat_observation(trailers_observation(np.zeros(8), 2, 4), "DAgger")
    flat = np.zeros(8, np.float32)
    assert flat_observation(flat, "DAgger") is flat


def test_torchrl_reads_the_dict_as_a_composite() -> None:
    torchrl_envs = pytest.importorskip("torchrl.envs")
    from torchrl.envs.utils import check_env_specs

    env = torchrl_envs.GymEnv(REVERSE, n_trailers=2, observation="trailers", max_trailers=4)
    check_env_specs(env)
    env.set_seed(0)
    data = env.rollout(5)
    assert data["next", "trailers"].shape == (5, 4, 2)
    assert data["next", "body"].shape == (5, 4)
    assert data["mask"][0].tolist() == [1.0, 1.0, 0.0, 0.0]


def test_goal_conditioned_needs_the_flat_observation() -> None:
    from trailer_env.wrappers import GoalConditioned

    with pytest.raises(ValueError, match="GoalConditioned needs the flat observation"):
        GoalConditioned(gym.make("trailer_env/Dock-v0", n_trailers=1, observation="trailers"))
