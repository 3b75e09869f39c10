"""The vector env's autoreset modes, reset options and rendering, checked against single envs."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from tests.trailer_env.helpers import make


def make_vec(num_envs: int, **kwargs: object) -> gym.vector.VectorEnv:
    return gym.make_vec(
        "trailer_env/Reverse-v0",
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        **kwargs,
    )


def run_until_first_end(envs: gym.vector.VectorEnv) -> tuple[list[np.ndarray], np.ndarray, dict]:
    """Zero actions until some environment ends (Reverse folds within a few seconds)."""
    observations = []
    for _ in range(200):
        obs, _, terminated, truncated, info = envs.step(np.zeros((envs.num_envs, 1)))
        observations.append(obs)
        if (terminated | truncated).any():
            return observations, terminated | truncated, info
    raise AssertionError("no episode ended")


def test_autoreset_mode_is_an_attribute_and_in_metadata() -> None:
    for mode in AutoresetMode:
        envs = make_vec(2, autoreset_mode=mode.value)
        assert envs.unwrapped.autoreset_mode == mode
        assert envs.metadata["autoreset_mode"] == mode
    with pytest.raises(ValueError, match="autoreset_mode"):
        make_vec(2, autoreset_mode="sometimes")


def test_same_step_reports_the_final_observation_and_resets_at_once() -> None:
    next_step = make_vec(3)
    same_step = make_vec(3, autoreset_mode="same_step")
    next_step.reset(seed=5)
    same_step.reset(seed=5)
    before, done, _ = run_until_first_end(next_step)
    after, done_same, info = run_until_first_end(same_step)
    np.testing.assert_array_equal(done, done_same)
    rows = np.flatnonzero(done)
    np.testing.assert_array_equal(info["_final_obs"], done)
    for i in rows.tolist():
        np.testing.assert_array_equal(info["final_obs"][i], before[-1][i])
        assert bool(info["final_info"]["jackknifed"][i]) or not info["final_info"]["is_success"][i]
    assert all(info["final_obs"][i] is None for i in np.flatnonzero(~done).tolist())
    # The reset observation is the one NEXT_STEP returns one step later, from the same generator.
    reset_obs, *_ = next_step.step(np.zeros((3, 1)))
    np.testing.assert_array_equal(after[-1][rows], reset_obs[rows])


def test_disabled_autoreset_needs_a_masked_reset() -> None:
    envs = make_vec(3, autoreset_mode="disabled")
    envs.reset(seed=5)
    _, done, _ = run_until_first_end(envs)
    with pytest.raises(RuntimeError, match="reset_mask"):
        envs.step(np.zeros((3, 1)))
    kept = envs.unwrapped.core.z[~done].copy()
    obs, _ = envs.reset(options={"reset_mask": done})
    np.testing.assert_array_equal(envs.unwrapped.core.z[~done], kept)  # the others untouched
    # The reset rows drew their second start from their own generators, like a single env.
    single = make("Reverse")
    single.reset(seed=5 + int(np.flatnonzero(done)[0]))
    second, _ = single.reset()
    np.testing.assert_array_equal(obs[np.flatnonzero(done)[0]], second)
    envs.step(np.zeros((3, 1)))


def test_reset_options_state_and_errors() -> None:
    envs = make_vec(2)
    states = np.array([[-1.0, 0.0, 0.01, -0.02], [-0.9, 0.01, 0.0, 0.03]])
    obs, info = envs.reset(seed=0, options={"state": states})
    np.testing.assert_array_equal(envs.unwrapped.core.z, states)
    np.testing.assert_allclose(obs[:, 0], states[:, 0])
    assert info["actuator_work"].tolist() == [0.0, 0.0]
    with pytest.raises(ValueError, match="unknown reset option"):
        envs.reset(options={"start": states})
    with pytest.raises(ValueError, match="shape"):
        envs.reset(options={"state": states[:1]})
    with pytest.raises(ValueError, match="reset_mask"):
        envs.reset(options={"reset_mask": np.array([1, 0])})
    with pytest.raises(TypeError, match="options"):
        envs.reset(options=["state"])  # type: ignore[arg-type]


def test_rgb_array_render_gives_one_frame_per_environment() -> None:
    envs = make_vec(3, render_mode="rgb_array", n_trailers=2)
    envs.reset(seed=1)
    frames = envs.render()
    assert len(frames) == 3 and all(frame.shape == (600, 600, 3) for frame in frames)
    assert not np.array_equal(frames[0], frames[1])  # different random starts
    single = make("Reverse", render_mode="rgb_array", n_trailers=2)
    single.reset(seed=2)
    for _ in range(5):
        single.step(np.array([0.5], np.float32))
        envs.step(np.full((3, 1), 0.5))
    np.testing.assert_array_equal(envs.render()[1], single.render())  # env 1 is seeded 1 + 1
    envs.close()


def test_bad_state_options_change_nothing() -> None:
    envs = make_vec(2)
    envs.reset(seed=0)
    before = envs.unwrapped.core.z.copy()
    generators = [g.bit_generator.state for g in envs.unwrapped._generators]
    for bad in ([[-1e200, 0, 0, 0]] * 2, [[-1.0, 0, 0, 0], [np.nan, 0, 0, 0]]):
        with pytest.raises(ValueError, match="z"):
            envs.reset(options={"state": np.array(bad)})
        np.testing.assert_array_equal(envs.unwrapped.core.z, before)
        assert [g.bit_generator.state for g in envs.unwrapped._generators] == generators
