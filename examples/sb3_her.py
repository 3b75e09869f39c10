"""stable-baselines3 SAC with hindsight experience replay on Heading-v0's goal view.

    python examples/sb3_her.py --steps 6000      # about two minutes on a core

:class:`trailer_env.wrappers.GoalConditioned` gives ``Dict`` observations and a
vectorised ``compute_reward``, which SB3's ``HerReplayBuffer`` relabels with. The
score runs the trained policy on the native batch with the same goal view
(``goal_conditioned=True``). Needs the ``agents`` extra.
"""

from __future__ import annotations

import argparse
import sys
import time

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3 import SAC, HerReplayBuffer
from stable_baselines3.common.callbacks import BaseCallback

import trailer_env  # noqa: F401  (registers the ids)
from trailer_env.benchmark import score
from trailer_env.wrappers import GoalConditioned


class PrintProgress(BaseCallback):
    """A line on stderr at each tenth of the steps: SAC on one core is slow to watch."""

    def __init__(self, total: int) -> None:
        super().__init__()
        self.total, self.every, self.started = total, max(1, total // 10), time.perf_counter()

    def _on_step(self) -> bool:
        if self.num_timesteps % self.every == 0:
            elapsed = time.perf_counter() - self.started
            print(
                f"sb3_her: {self.num_timesteps}/{self.total} steps, {elapsed:.0f} s",
                file=sys.stderr,
                flush=True,
            )
        return True


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--env", default="trailer_env/Heading-v0")
    parser.add_argument("--n-trailers", type=int, default=1)
    parser.add_argument("--steps", type=int, default=6000)
    parser.add_argument("--episodes", type=int, default=100)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    env = GoalConditioned(gym.make(args.env, n_trailers=args.n_trailers))
    episode_steps = env.unwrapped.core.max_episode_steps  # type: ignore[attr-defined]
    model = SAC(
        "MultiInputPolicy",
        env,
        replay_buffer_class=HerReplayBuffer,
        replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
        learning_starts=episode_steps + 1,  # HER samples whole episodes
        seed=0,
    )
    print(f"sb3_her: SAC + HER for {args.steps} steps ...", file=sys.stderr, flush=True)
    model.learn(args.steps, callback=PrintProgress(args.steps))
    print(f"sb3_her: scoring {args.episodes} episodes ...", file=sys.stderr, flush=True)

    def act(obs: dict[str, np.ndarray]) -> np.ndarray:
        return model.predict(obs, deterministic=True)[0]

    result = score(
        act,
        args.env,
        args.n_trailers,
        name="sac-her",
        episodes=args.episodes,
        goal_conditioned=True,
    )
    print(result.markdown)
    return result.summary


if __name__ == "__main__":
    main()
