"""The convoy's mirror image is a symmetry of every scene: mirrored episodes mirror."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import trailer_env  # noqa: F401  (registers the ids)
from trailer_env.mixed import pad_observations
from trailer_env.registry import ENVIRONMENTS


def _mirrored(state: dict[str, object], n: int) -> dict[str, object]:
    z = np.array(state["z"], dtype=np.float64)
    z[1 : 2 + n] *= -1.0  # omega and the hitch angles
    if z.size > n + 2:
        z[n + 3 : n + 5] *= -1.0  # the pose's y and theta
    mirrored: dict[str, object] = {"z": z, "s": -float(state["s"]), "s_dot": -float(state["s_dot"])}  # type: ignore[arg-type]
    if "target" in state:
        x, y, heading = np.asarray(state["target"], dtype=np.float64)
        mirrored["target"] = np.array([x, -y, -heading])
    if "target_heading" in state:
        mirrored["target_heading"] = -float(state["target_heading"])  # type: ignore[arg-type]
    return mirrored


CASES = [
    (env_id, {"action_mode": mode})
    for env_id in sorted(ENVIRONMENTS)
    for mode in ("servo", "accel", "planar")
]
CASES.append(("trailer_env/Reverse-v1", {"randomize": "mismatch20", "observe_params": True}))


@pytest.mark.parametrize(("env_id", "kwargs"), CASES)
def test_a_mirrored_episode_is_the_mirror_image(env_id: str, kwargs: dict[str, object]) -> None:
    n = 2
    env = gym.make(env_id, n_trailers=n, **kwargs)
    image = gym.make(env_id, n_trailers=n, **kwargs)
    env.reset(seed=3)
    state = env.unwrapped.get_state()  # type: ignore[attr-defined]
    signs = env.unwrapped.core.mirror_signs()  # type: ignore[attr-defined]
    assert signs is not None
    obs_signs, action_signs = signs
    image.reset(seed=3)
    obs = env.unwrapped.set_state(**state)  # type: ignore[attr-defined]
    mirrored = image.unwrapped.set_state(**_mirrored(state, n))  # type: ignore[attr-defined]
    assert obs_signs.shape == obs.shape
    np.testing.assert_allclose(mirrored, obs * obs_signs, rtol=0, atol=1e-6)
    rng = np.random.default_rng(0)
    for _ in range(60):
        action = rng.uniform(-1.0, 1.0, env.action_space.shape).astype(np.float32)
        obs, reward, terminated, truncated, _ = env.step(action)
        mirrored, image_reward, image_terminated, _, _ = image.step(action * action_signs)
        np.testing.assert_allclose(mirrored, obs * obs_signs, rtol=1e-6, atol=1e-6)
        assert image_reward == pytest.approx(reward, rel=1e-9, abs=1e-12)
        assert image_terminated == terminated
        if terminated or truncated:
            break


@pytest.mark.parametrize("env_id", sorted(ENVIRONMENTS))
def test_the_padded_layout_mirrors_every_count_it_holds(env_id: str) -> None:

    mixed = gym.make_vec(
        env_id, num_envs=1, vectorization_mode="vector_entry_point", n_trailers=(1, 3)
    )
    signs = mixed.unwrapped.core.mirror_signs()  # type: ignore[attr-defined]
    assert signs is not None
    padded_signs, padded_action = signs
    assert padded_signs.shape == mixed.single_observation_space.shape
    for n in (1, 2, 3):
        single = gym.make(env_id, n_trailers=n)
        obs_signs, action_signs = single.unwrapped.core.mirror_signs()  # type: ignore[attr-defined]
        obs = np.random.default_rng(n).normal(size=(4, obs_signs.size)).astype(np.float32)
        np.testing.assert_array_equal(
            pad_observations(obs, n, 3) * padded_signs, pad_observations(obs * obs_signs, n, 3)
        )
        np.testing.assert_array_equal(padded_action, action_signs)
