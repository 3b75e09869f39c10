"""Training-time reward wrappers (evaluation always uses the environment's own reward).

:class:`ForwardPenalty` closes a loophole of Reverse-v0 for training: the moving
mass can do work on the convoy, brake it and push it forwards, where a straight
convoy is stable. The scene charges 0.5 per forward step, less than the 1 per
step a straight convoy earns, so "stop reversing" is a cheap way not to fold.
Adding a larger charge per forward step makes folding no worse than escaping,
so the agent has to keep reversing and learn to stabilise the unstable motion.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper
from stable_baselines3.common.vec_env.base_vec_env import VecEnvStepReturn


class ForwardPenalty(VecEnvWrapper):
    """Subtract ``penalty`` from the reward of every step that ends with the cart moving forwards.

    The speed is observation 0 (u) in every scene; on a step that ends an episode it is
    read from the terminal observation.

    Args:
        venv: The SB3 vector env (a trailer_env scene).
        penalty: Reward subtracted per forward step (>= 0).
    """

    def __init__(self, venv: VecEnv, penalty: float) -> None:
        if not penalty >= 0.0:
            raise ValueError(f"penalty must be >= 0, got {penalty}")
        super().__init__(venv)
        self.penalty = float(penalty)

    def reset(self) -> Any:
        return self.venv.reset()

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, dones, infos = self.venv.step_wait()
        speed = np.array(np.asarray(obs)[:, 0], dtype=np.float64)
        for i in np.flatnonzero(dones):
            speed[i] = infos[i]["terminal_observation"][0]
        rewards = rewards - self.penalty * (speed > 0.0).astype(rewards.dtype)
        return obs, rewards, dones, infos
