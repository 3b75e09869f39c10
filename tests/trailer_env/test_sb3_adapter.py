"""The stable-baselines3 adapter over the batch core, and SB3's own multiprocess vector env."""

from __future__ import annotations

import numpy as np
import pytest
from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import SubprocVecEnv, VecMonitor

from tests.trailer_env.helpers import make
from trailer_env.sb3 import ConvoySB3VecEnv


def test_same_step_reset_with_terminal_observation() -> None:
    venv = ConvoySB3VecEnv("trailer_env/Reverse-v0", num_envs=2, max_episode_steps=4, n_trailers=1)
    venv.seed(0)
    venv.reset()
    for _ in range(3):
        _, _, dones, _ = venv.step(np.zeros((2, 1)))
        assert not dones.any()
    obs, rewards, dones, infos = venv.step(np.zeros((2, 1)))
    assert dones.all() and rewards.dtype == np.float32
    for i in range(2):
        assert infos[i]["TimeLimit.truncated"] is True
        terminal = infos[i]["terminal_observation"]
        assert terminal.shape == obs[i].shape and not np.array_equal(terminal, obs[i])
        assert np.all(obs[i][-2:] == 0.0)  # a fresh episode: the mass at rest at the centre
        assert type(infos[i]["is_success"]) is bool and type(infos[i]["cost"]) is float


def test_adapter_replays_the_single_env_seeded_seed_plus_i(rng: np.random.Generator) -> None:
    count, seed = 3, 21
    venv = ConvoySB3VecEnv("trailer_env/Coast-v0", num_envs=count, n_trailers=2)
    singles = [make("Coast", n_trailers=2) for _ in range(count)]
    venv.seed(seed)
    obs = venv.reset()
    for i, env in enumerate(singles):
        np.testing.assert_array_equal(obs[i], env.reset(seed=seed + i)[0])
    ended = 0
    for _ in range(120):
        actions = rng.uniform(-1, 1, (count, 1)).astype(np.float32)
        obs, rewards, dones, infos = venv.step(actions)
        for i, env in enumerate(singles):
            single_obs, reward, terminated, truncated, _ = env.step(actions[i])
            assert reward == pytest.approx(rewards[i], rel=1e-6)
            assert dones[i] == (terminated or truncated)
            if dones[i]:
                ended += 1
                np.testing.assert_array_equal(infos[i]["terminal_observation"], single_obs)
                single_obs, _ = env.reset()
            np.testing.assert_array_equal(obs[i], single_obs)
    assert ended > 0


def test_ppo_trains_on_the_adapter() -> None:
    venv = ConvoySB3VecEnv("trailer_env/Reverse-v0", num_envs=8, n_trailers=1)
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=256)
    action, _ = model.predict(venv.reset(), deterministic=True)
    assert action.shape == (8, 1)


def test_adapter_rejects_bad_input() -> None:
    with pytest.raises(ValueError, match="mu"):
        ConvoySB3VecEnv("trailer_env/Reverse-v0", num_envs=2, mu=-1.0)
    with pytest.raises(ValueError, match="unknown environment"):
        ConvoySB3VecEnv("CartPole-v1", num_envs=2)
    venv = ConvoySB3VecEnv("trailer_env/Reverse-v0", num_envs=2)
    venv.reset()
    with pytest.raises(ValueError, match="non-finite"):
        venv.step(np.array([[0.0], [np.inf]]))


def test_subproc_vec_env_pickles_and_steps() -> None:
    """SB3's SubprocVecEnv pickles the env factory into fresh worker processes.

    The workers have not imported trailer_env: the module-prefixed id imports it.
    """
    venv = make_vec_env(
        "trailer_env:trailer_env/Dock-v0", n_envs=2, seed=3, vec_env_cls=SubprocVecEnv
    )
    try:
        obs = venv.reset()
        for _ in range(5):
            obs, _, _, _ = venv.step(np.zeros((2, 1), dtype=np.float32))
        reference = make("Dock")
        expected = reference.reset(seed=4)[0]
        for _ in range(5):
            expected = reference.step(np.zeros(1, dtype=np.float32))[0]
        np.testing.assert_array_equal(obs[1], expected)
    finally:
        venv.close()


def test_adapter_records_episodes_like_vecmonitor() -> None:
    kwargs = {"num_envs": 3, "max_episode_steps": 60, "n_trailers": 2}
    native = ConvoySB3VecEnv("trailer_env/Reverse-v0", **kwargs)
    with pytest.warns(UserWarning, match="already wrapped with a `Monitor`"):
        monitored = VecMonitor(ConvoySB3VecEnv("trailer_env/Reverse-v0", **kwargs))
    native.seed(2)
    monitored.seed(2)
    native.reset()
    monitored.reset()
    ours, theirs = [], []
    for _ in range(130):
        *_, infos = native.step(np.zeros((3, 1)))
        *_, monitor_infos = monitored.step(np.zeros((3, 1)))
        ours += [(i["episode"]["r"], i["episode"]["l"]) for i in infos if "episode" in i]
        theirs += [(i["episode"]["r"], i["episode"]["l"]) for i in monitor_infos if "episode" in i]
    assert len(ours) >= 6 and [length for _, length in ours] == [length for _, length in theirs]
    np.testing.assert_allclose([r for r, _ in ours], [r for r, _ in theirs], rtol=1e-6)
    from stable_baselines3.common.monitor import Monitor

    assert native.env_is_wrapped(Monitor) == [True, True, True]
    model = PPO("MlpPolicy", native, n_steps=64, batch_size=64, n_epochs=1, seed=0)
    model.learn(256)
    assert len(model.ep_info_buffer) >= 3  # SB3's logger sees the episodes without a wrapper


def test_infos_are_built_when_read_and_equal_the_eager_dicts() -> None:
    venv = ConvoySB3VecEnv("trailer_env/Reverse-v1", num_envs=4, max_episode_steps=5, n_trailers=2)
    venv.seed(3)
    venv.reset()
    for _ in range(4):
        *_, infos = venv.step(np.zeros((4, 1), dtype=np.float32))
    core = venv.core
    assert len(infos) == 4 and infos[-1] is infos[3]  # built once, then kept
    for i in range(4):
        expected = core.info_row(i)
        assert infos[i] == expected and type(infos[i]["jackknifed"]) is bool
    assert infos[1:3] == [infos[1], infos[2]] and list(infos) == [infos[i] for i in range(4)]
    with pytest.raises(IndexError, match="out of range for 4"):
        infos[4]
    obs, _, dones, infos = venv.step(np.zeros((4, 1), dtype=np.float32))  # the time limit
    assert dones.all()
    infos[0]["terminal_observation"] = "rewritten"  # VecNormalize writes into them
    assert infos[0]["terminal_observation"] == "rewritten"
    assert infos[2]["episode"]["l"] == 5 and infos[2]["TimeLimit.truncated"] is True
    assert infos[2]["terminal_observation"].shape == obs[2].shape


def test_float32_and_float64_actions_step_the_same_bits(rng: np.random.Generator) -> None:
    actions = rng.uniform(-1.2, 1.2, (40, 3, 1)).astype(np.float32)
    runs = []
    for dtype in (np.float32, np.float64):
        venv = ConvoySB3VecEnv("trailer_env/Coast-v0", num_envs=3, n_trailers=2)
        venv.seed(5)
        venv.reset()
        runs.append([venv.step(action.astype(dtype))[0] for action in actions])
    np.testing.assert_array_equal(np.array(runs[0]), np.array(runs[1]))
    assert np.abs(np.array(runs[0])[:, :, 0]).min() > 0.0
