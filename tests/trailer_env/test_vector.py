"""The native vector env: NEXT_STEP autoreset, seeding, determinism against the single env."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from tests.trailer_env.helpers import SCENE_IDS, make, rollout
from trailer_env.vector import ConvoyVectorEnv


def make_vec(env_id: str, num_envs: int, **kwargs: object) -> gym.vector.VectorEnv:
    return gym.make_vec(
        env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs
    )


def test_make_vec_builds_the_native_batch() -> None:
    envs = make_vec("trailer_env/Reverse-v0", 3, n_trailers=1, mu=0.4)
    assert isinstance(envs.unwrapped, ConvoyVectorEnv)
    assert envs.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert envs.unwrapped.max_episode_steps == 400
    assert envs.unwrapped.settings.params.mu == 0.4
    assert envs.observation_space.shape == (3, 6)
    assert envs.action_space.shape == (3, 1)
    obs, infos = envs.reset(seed=0)
    assert envs.observation_space.contains(obs)
    assert infos["cost"].shape == (3,) and infos["_cost"].all()


def test_same_seed_same_trajectory_single_env(rng: np.random.Generator) -> None:
    actions = rng.uniform(-1, 1, (150, 1)).astype(np.float32)
    first = rollout(make("Reverse", n_trailers=3), actions, seed=11)
    second = rollout(make("Reverse", n_trailers=3), actions, seed=11)
    np.testing.assert_array_equal(first[0], second[0])
    np.testing.assert_array_equal(first[1], second[1])
    other = rollout(make("Reverse", n_trailers=3), actions, seed=12)
    assert not np.array_equal(first[0][:5], other[0][:5])


@pytest.mark.parametrize("env_id", SCENE_IDS)
def test_vector_env_matches_single_envs_seeded_seed_plus_i(
    rng: np.random.Generator, env_id: str
) -> None:
    """Env i of make_vec(seed=s) replays gym.make + reset(seed=s + i), autoresets included."""
    _assert_vector_replays_singles(env_id, rng)


def test_vector_env_replays_single_envs_with_dopri5(rng: np.random.Generator) -> None:
    # The adaptive integrator keeps per-row state; the batch still replays single envs.
    _assert_vector_replays_singles("trailer_env/Reverse-v0", rng, fidelity="dopri5")


def _assert_vector_replays_singles(env_id: str, rng: np.random.Generator, **kwargs: object) -> None:
    count, steps, seed = 3, 160, 40
    envs = make_vec(env_id, count, n_trailers=2, max_episode_steps=60, **kwargs)
    singles = [gym.make(env_id, n_trailers=2, max_episode_steps=60, **kwargs) for _ in range(count)]
    vector_obs, _ = envs.reset(seed=seed)
    single_obs = np.stack([env.reset(seed=seed + i)[0] for i, env in enumerate(singles)])
    np.testing.assert_array_equal(vector_obs, single_obs)
    done = [False] * count
    episodes = 0
    for _ in range(steps):
        actions = rng.uniform(-1.5, 1.5, (count, 1)).astype(np.float32)
        vector_obs, rewards, terminated, truncated, infos = envs.step(actions)
        for i, env in enumerate(singles):
            if done[i]:  # NEXT_STEP: this step resets env i and ignores its action
                obs, _ = env.reset()
                reward, term, trunc = 0.0, False, False
                episodes += 1
            else:
                obs, reward, term, trunc, info = env.step(actions[i])
                assert info["energy"] == infos["energy"][i]
            np.testing.assert_array_equal(obs, vector_obs[i])
            assert reward == rewards[i] and term == terminated[i] and trunc == truncated[i]
            done[i] = term or trunc
    assert episodes >= count  # autoresets really happened


def test_same_seed_same_trajectory_vector_env(rng: np.random.Generator) -> None:
    actions = rng.uniform(-1, 1, (120, 4, 1)).astype(np.float32)
    runs = []
    for _ in range(2):
        envs = make_vec("trailer_env/Coast-v0", 4)
        trace = [envs.reset(seed=5)[0]]
        trace += [envs.step(a)[0] for a in actions]
        runs.append(np.array(trace))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_next_step_autoreset_and_truncation() -> None:
    envs = make_vec("trailer_env/Reverse-v0", 2, max_episode_steps=5)
    envs.reset(seed=0)
    for _ in range(4):
        _, _, terminated, truncated, _ = envs.step(np.zeros((2, 1), dtype=np.float32))
        assert not truncated.any()
    obs, rewards, terminated, truncated, _ = envs.step(np.zeros((2, 1), dtype=np.float32))
    assert truncated.all() and not terminated.any()
    obs, rewards, terminated, truncated, infos = envs.step(np.ones((2, 1), dtype=np.float32))
    # The reset step: first observations of new episodes, zero reward, mass at rest at the centre.
    assert (rewards == 0.0).all() and not (terminated | truncated).any()
    assert np.all(obs[:, -2:] == 0.0) and np.all(infos["actuator_work"] == 0.0)
    assert np.all(envs.unwrapped.elapsed_steps == 0)


def test_reset_with_a_list_of_seeds() -> None:
    envs = make_vec("trailer_env/Dock-v0", 2)
    obs, _ = envs.reset(seed=[7, 3])
    single = make("Dock")
    np.testing.assert_array_equal(obs[0], single.reset(seed=7)[0])
    np.testing.assert_array_equal(obs[1], single.reset(seed=3)[0])
    with pytest.raises(ValueError, match="seed"):
        envs.reset(seed=[1, 2, 3])


def test_vector_bad_actions() -> None:
    envs = make_vec("trailer_env/Reverse-v0", 3)
    envs.reset(seed=0)
    actions = np.zeros((3, 1), dtype=np.float32)
    actions[1] = np.nan
    before = envs.unwrapped.core.z.copy()
    with pytest.raises(ValueError, match="environment 1"):
        envs.step(actions)
    np.testing.assert_array_equal(envs.unwrapped.core.z, before)
    with pytest.raises(ValueError, match="shape"):
        envs.step(np.zeros((2, 1)))
    envs.step(np.zeros(3))  # (N,) is accepted for 1-D actions
    with pytest.raises(ValueError, match="render_mode"):
        make_vec("trailer_env/Reverse-v0", 2, render_mode="human")


def test_large_batches_use_the_parallel_kernels_with_identical_results(
    rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch
) -> None:
    import trailer_env.core_base
    from trailer_env.kernels import PARALLEL_MIN_ROWS, step_parallel

    calls = []

    def counting(*args: object) -> tuple:
        calls.append(1)
        return step_parallel(*args)  # type: ignore[no-any-return]

    monkeypatch.setattr(trailer_env.core_base, "step_parallel", counting)
    count = PARALLEL_MIN_ROWS + 3  # an odd-sized last chunk
    envs = make_vec("trailer_env/Heading-v0", count)
    checked = [0, count // 2, count - 1]
    singles = {i: make("Heading") for i in checked}
    obs, _ = envs.reset(seed=9)
    for i, env in singles.items():
        np.testing.assert_array_equal(obs[i], env.reset(seed=9 + i)[0])
    for _ in range(15):
        actions = rng.uniform(-1, 1, (count, 1)).astype(np.float32)
        obs, rewards, *_ = envs.step(actions)
        for i, env in singles.items():
            single_obs, reward, *_ = env.step(actions[i])
            np.testing.assert_array_equal(obs[i], single_obs)
            assert reward == rewards[i]
    assert len(calls) == 15  # every step went through the parallel kernel
