"""CleanRL-style PPO in one file on the native vector env, ending with the benchmark score.

    python examples/cleanrl_ppo.py --total-steps 200000      # about a minute on a core

The env is ``gym.make_vec(..., vectorization_mode="vector_entry_point")``: one compiled
call steps all convoys. ``autoreset_mode="same_step"`` returns the next episode's first
observation on the step that ends one, which is what this loop's bootstrap expects.
Needs the ``agents`` extra (torch).
"""

from __future__ import annotations

import argparse
import sys
import time

import gymnasium as gym
import numpy as np
import torch
from torch import nn

import trailer_env  # noqa: F401  (registers the ids)
from trailer_env.benchmark import score


class Agent(nn.Module):
    def __init__(self, obs_dim: int, action_dim: int) -> None:
        super().__init__()
        self.critic = nn.Sequential(nn.Linear(obs_dim, 64), nn.Tanh(), nn.Linear(64, 1))
        self.actor = nn.Sequential(nn.Linear(obs_dim, 64), nn.Tanh(), nn.Linear(64, action_dim))
        self.log_std = nn.Parameter(torch.full((action_dim,), -0.5))

    def distribution(self, obs: torch.Tensor) -> torch.distributions.Normal:
        return torch.distributions.Normal(self.actor(obs), self.log_std.exp())


def train(env_id: str, n_trailers: int, total_steps: int, num_envs: int, seed: int) -> Agent:
    torch.manual_seed(seed)
    envs = gym.make_vec(
        env_id,
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        autoreset_mode="same_step",
        n_trailers=n_trailers,
    )
    obs_dim = envs.single_observation_space.shape[0]
    action_dim = envs.single_action_space.shape[0]
    agent = Agent(obs_dim, action_dim)
    optimizer = torch.optim.Adam(agent.parameters(), lr=3e-4)
    steps, gamma, lam = 128, 0.99, 0.95
    obs = torch.as_tensor(envs.reset(seed=seed)[0], dtype=torch.float32)
    updates = max(1, total_steps // (steps * num_envs))
    started = time.perf_counter()
    for update in range(updates):
        if update % max(1, updates // 10) == 0:  # progress on stderr, about 10 lines in all
            print(
                f"cleanrl_ppo: update {update + 1}/{updates}, {update * steps * num_envs} "
                f"steps, {time.perf_counter() - started:.0f} s",
                file=sys.stderr,
                flush=True,
            )
        transitions = []
        for _ in range(steps):
            with torch.no_grad():
                dist = agent.distribution(obs)
                action = dist.sample()
                value = agent.critic(obs).squeeze(-1)
            next_obs, reward, terminated, truncated, _ = envs.step(action.clamp(-1, 1).numpy())
            done = torch.as_tensor(terminated | truncated, dtype=torch.float32)
            log_prob = dist.log_prob(action).sum(-1)
            transitions.append((obs, action, log_prob, torch.as_tensor(reward), done, value))
            obs = torch.as_tensor(next_obs, dtype=torch.float32)
        o, a, logp, r, d, v = (torch.stack(column) for column in zip(*transitions, strict=True))
        with torch.no_grad():
            advantages = torch.zeros_like(r)
            last, next_value = torch.zeros(num_envs), agent.critic(obs).squeeze(-1)
            for t in reversed(range(steps)):
                delta = r[t] + gamma * next_value * (1 - d[t]) - v[t]
                last = delta + gamma * lam * (1 - d[t]) * last
                advantages[t], next_value = last, v[t]
            returns = advantages + v
        rollout = (o, a, logp, advantages, returns)
        flat = [x.reshape(steps * num_envs, *x.shape[2:]) for x in rollout]
        for _ in range(4):
            for batch in torch.randperm(steps * num_envs).split(512):
                bo, ba, blogp, badv, bret = (x[batch] for x in flat)
                ratio = (agent.distribution(bo).log_prob(ba).sum(-1) - blogp).exp()
                badv = (badv - badv.mean()) / (badv.std() + 1e-8)
                policy_loss = -torch.min(ratio * badv, ratio.clamp(0.8, 1.2) * badv).mean()
                value_loss = ((agent.critic(bo).squeeze(-1) - bret) ** 2).mean()
                optimizer.zero_grad()
                (policy_loss + 0.5 * value_loss).backward()
                optimizer.step()
    envs.close()
    return agent


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--env", default="trailer_env/Reverse-v1")
    parser.add_argument("--n-trailers", type=int, default=1)
    parser.add_argument("--total-steps", type=int, default=200_000)
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--episodes", type=int, default=100)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    agent = train(args.env, args.n_trailers, args.total_steps, args.num_envs, seed=0)

    def policy(obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return agent.actor(torch.as_tensor(obs, dtype=torch.float32)).clamp(-1, 1).numpy()

    print(f"cleanrl_ppo: scoring {args.episodes} episodes ...", file=sys.stderr, flush=True)
    result = score(policy, args.env, args.n_trailers, name="cleanrl-ppo", episodes=args.episodes)
    print(result.markdown)
    return result.summary


if __name__ == "__main__":
    main()
