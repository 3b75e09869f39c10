"""Registration: string entry points, so every id's spec goes to JSON and back."""

from __future__ import annotations

import json
import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.envs.registration import EnvSpec

import trailer_env  # noqa: F401  (registers the ids)
from trailer_env import registry
from trailer_env.registry import ENVIRONMENTS, VECTOR_ENVIRONMENTS
from trailer_env.vector import ConvoyVectorEnv

IDS = list(ENVIRONMENTS)


@pytest.mark.parametrize("env_id", IDS)
def test_the_spec_goes_to_json_and_back(env_id: str) -> None:
    env = gym.make(env_id, n_trailers=1)
    text = env.spec.to_json()
    record = json.loads(text)
    assert record["id"] == env_id and record["kwargs"] == {"n_trailers": 1}
    assert record["max_episode_steps"] == ENVIRONMENTS[env_id].core_class.max_episode_steps
    spec = EnvSpec.from_json(text)
    registered = gym.spec(env_id)
    assert (spec.id, spec.entry_point, spec.vector_entry_point) == (
        env_id,
        registered.entry_point,
        registered.vector_entry_point,
    )
    again = gym.make(spec)
    assert type(again.unwrapped) is ENVIRONMENTS[env_id]
    assert again.unwrapped.core.n == 1
    first, _ = env.reset(seed=4)
    second, _ = again.reset(seed=4)
    np.testing.assert_array_equal(first, second)
    action = np.full(env.action_space.shape, 0.3, dtype=np.float32)
    assert env.step(action)[1] == again.step(action)[1]
    assert again.spec.to_json() == text


@pytest.mark.parametrize("env_id", IDS)
def test_the_vector_entry_point_is_a_named_class(env_id: str) -> None:
    entry = gym.spec(env_id).vector_entry_point
    assert isinstance(entry, str)
    module, name = entry.split(":")
    cls = getattr(registry, name)
    assert module == "trailer_env.registry" and cls is VECTOR_ENVIRONMENTS[env_id]
    assert issubclass(cls, ConvoyVectorEnv) and pickle.loads(pickle.dumps(cls)) is cls
    spec = EnvSpec.from_json(gym.make(env_id).spec.to_json())
    envs = gym.make_vec(spec, num_envs=2, vectorization_mode="vector_entry_point", n_trailers=1)
    assert type(envs) is cls and envs.unwrapped.core_class is ENVIRONMENTS[env_id].core_class
    obs, _ = envs.reset(seed=4)
    single = gym.make(env_id, n_trailers=1)
    np.testing.assert_array_equal(obs[0], single.reset(seed=4)[0])
    envs.close()


def test_the_vector_spec_says_the_truncation_it_applies() -> None:
    envs = gym.make_vec(
        "trailer_env/Reverse-v1",
        num_envs=2,
        vectorization_mode="vector_entry_point",
        max_episode_steps=10,
    )
    assert envs.spec is not None and envs.spec.max_episode_steps == 10
    envs.reset(seed=0)
    for _ in range(9):
        _, _, _, truncated, _ = envs.step(np.zeros((2, 1), dtype=np.float32))
        assert not truncated.any()
    _, _, terminated, truncated, _ = envs.step(np.zeros((2, 1), dtype=np.float32))
    assert (truncated | terminated).all()
    default = gym.make_vec(
        "trailer_env/Reverse-v1", num_envs=2, vectorization_mode="vector_entry_point"
    )
    assert default.spec is not None and default.spec.max_episode_steps == 400
