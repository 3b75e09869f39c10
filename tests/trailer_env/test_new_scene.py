"""A scene written with Python hooks only, as CONTRIBUTING's "Adding a scene" shows it:
its declared objective gives its termination."""

from __future__ import annotations

import numpy as np

from trailer_env.core import ConvoyCore
from trailer_env.env import ConvoyEnv
from trailer_env.objective import Objective


class HoldCore(ConvoyCore):
    """Survive: reverse slowly for 50 steps without folding (success = not failed yet)."""

    scene = "Hold"
    objective = Objective.SURVIVAL
    max_episode_steps = 50
    failure_words = "the convoy stopped reversing"

    def _reset_row(self, i: int, rng: np.random.Generator) -> None:
        self.z[i, 0] = -rng.uniform(0.8, 1.2)

    def _is_failed(self) -> np.ndarray:
        return self.z[:, 0] >= 0.0

    def _is_success(self) -> np.ndarray:
        return ~(self.jackknifed | (self.z[:, 0] >= 0.0))

    def _reward(self) -> np.ndarray:
        return np.where(self.failed | self.jackknifed, -10.0, 1.0)


class ReachCore(HoldCore):
    """The same hooks declared a goal scene: the success ends the episode."""

    objective = Objective.GOAL


class HoldEnv(ConvoyEnv):
    core_class = HoldCore


class ReachEnv(ConvoyEnv):
    core_class = ReachCore


def _steps_until_the_end(env: ConvoyEnv) -> tuple[int, bool]:
    env.reset(seed=0)
    for step in range(1, 51):
        _, reward, terminated, _, info = env.step(np.zeros(1, np.float32))
        assert reward == 1.0
        if terminated:
            return step, bool(info["is_success"])
    return 50, False


def test_the_objective_gives_the_default_termination() -> None:
    # Survival: only a fold or a failure ends the episode (the time limit truncates it).
    assert _steps_until_the_end(HoldEnv(n_trailers=1)) == (50, False)
    # Goal: the first success ends it.
    assert _steps_until_the_end(ReachEnv(n_trailers=1)) == (1, True)
