"""The training-time forward-motion penalty."""

from __future__ import annotations

import numpy as np
import pytest

from agents.envs import make_sb3_env
from agents.wrappers import ForwardPenalty

COAST = "trailer_env/Coast-v0"  # starts forwards or backwards at random


def test_forward_steps_are_charged_exactly_the_penalty() -> None:
    plain = make_sb3_env(COAST, 8, {"n_trailers": 1}, seed=3)
    charged = ForwardPenalty(make_sb3_env(COAST, 8, {"n_trailers": 1}, seed=3), penalty=2.0)
    np.testing.assert_array_equal(plain.reset(), charged.reset())
    rng = np.random.default_rng(0)
    forward_seen = backward_seen = 0
    for _ in range(60):
        actions = rng.uniform(-1, 1, (8, 1)).astype(np.float32)
        obs, reward, dones, infos = plain.step(actions)
        _, charged_reward, _, _ = charged.step(actions)
        speed = np.array([infos[i]["terminal_observation"][0] if d else obs[i, 0]
                          for i, d in enumerate(dones)])  # fmt: skip
        np.testing.assert_allclose(charged_reward, reward - 2.0 * (speed > 0), rtol=1e-6)
        forward_seen += int(np.sum(speed > 0))
        backward_seen += int(np.sum(speed < 0))
    assert forward_seen > 0 and backward_seen > 0


def test_negative_penalty_is_refused() -> None:
    with pytest.raises(ValueError, match="penalty must be >= 0"):
        ForwardPenalty(make_sb3_env(COAST, 1), penalty=-1.0)
