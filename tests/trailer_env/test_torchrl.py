"""TorchRL: GymEnv by id, GymWrapper over the single env and over the native vector env."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

torchrl_envs = pytest.importorskip("torchrl.envs")
from torchrl.envs.utils import check_env_specs  # noqa: E402

import trailer_env  # noqa: E402, F401


def test_gym_env_by_id_passes_check_env_specs() -> None:
    # TorchRL probes the optional keyword `frameskip` and expects Python's TypeError.
    env = torchrl_envs.GymEnv("trailer_env/Reverse-v0", n_trailers=1)
    check_env_specs(env)
    env.set_seed(0)
    rollout = env.rollout(30)
    assert rollout["next", "observation"].shape == (30, 6)
    assert float(rollout["observation"][0, 0]) < -0.7  # reversing at 0.8 .. 1.2 m/s


def test_gym_wrapper_over_the_single_env() -> None:
    env = torchrl_envs.GymWrapper(gym.make("trailer_env/Coast-v0", n_trailers=2))
    check_env_specs(env)
    env.set_seed(0)  # unseeded, a random start may end within the rollout
    rollout = env.rollout(200, break_when_any_done=False)
    assert rollout["next", "reward"].shape == (200, 1)
    assert rollout["next", "done"].any()  # an episode ended and TorchRL reset it


@pytest.mark.parametrize("mode", ["disabled", "same_step"])
def test_gym_wrapper_over_the_native_vector_env(mode: str) -> None:
    venv = gym.make_vec(
        "trailer_env/Reverse-v0",
        num_envs=4,
        vectorization_mode="vector_entry_point",
        autoreset_mode=mode,
    )
    env = torchrl_envs.GymWrapper(venv)
    assert tuple(env.batch_size) == (4,)
    check_env_specs(env)
    env.set_seed(0)
    rollout = env.rollout(200, break_when_any_done=False)
    done = rollout["next", "done"].squeeze(-1).numpy()
    assert done.sum() >= 4  # zero actions fold the reversing convoy within ~3 s
    observations = rollout["observation"].numpy()
    env_index, step = np.argwhere(done[:, :-1])[0]
    # After a done, the next step starts from a fresh reversing start (mass centred, at rest).
    fresh = observations[env_index, step + 1]
    assert -1.2 <= fresh[0] <= -0.8 and np.all(fresh[-2:] == 0.0)
