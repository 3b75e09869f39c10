"""Shared helpers of the trailer_env tests."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

import trailer_env

SCENE_IDS = list(trailer_env.ENVIRONMENTS)


def make(scene: str, **kwargs: Any) -> gym.Env:
    """gym.make of a scene by short name ("Reverse") or full id."""
    env_id = scene if "/" in scene else f"trailer_env/{scene}-v0"
    return gym.make(env_id, **kwargs)


def rollout(
    env: gym.Env, actions: np.ndarray, seed: int
) -> tuple[np.ndarray, np.ndarray, list[bool]]:
    """Observations, rewards and done flags of one seeded rollout, resetting after each episode."""
    obs, _ = env.reset(seed=seed)
    observations = [obs]
    rewards = []
    dones = []
    for action in actions:
        obs, reward, terminated, truncated, _ = env.step(action)
        observations.append(obs)
        rewards.append(reward)
        dones.append(terminated or truncated)
        if terminated or truncated:
            obs, _ = env.reset()
            observations.append(obs)
    return np.array(observations), np.array(rewards), dones
