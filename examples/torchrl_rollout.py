"""TorchRL: the env through ``torchrl.envs.GymEnv``, a TensorDict policy, and its score.

    python examples/torchrl_rollout.py

Needs the ``torchrl`` extra. TorchRL's ``GymEnv`` builds the registered id itself;
the same network then acts on the native batch through :func:`trailer_env.benchmark.score`.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import torch
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.envs import GymEnv

import trailer_env  # noqa: F401  (registers the ids)
from trailer_env.benchmark import score


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--env", default="trailer_env/Reverse-v1")
    parser.add_argument("--n-trailers", type=int, default=2)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--episodes", type=int, default=100)
    args = parser.parse_args(argv)
    torch.manual_seed(0)
    env = GymEnv(args.env, n_trailers=args.n_trailers)
    obs_dim = env.observation_spec["observation"].shape[-1]
    network = nn.Sequential(nn.Linear(obs_dim, 32), nn.Tanh(), nn.Linear(32, 1), nn.Tanh())
    policy = TensorDictModule(network, in_keys=["observation"], out_keys=["action"])
    print(f"torchrl_rollout: {args.steps} steps through GymEnv ...", file=sys.stderr, flush=True)
    rollout = env.rollout(args.steps, policy)
    reward = float(rollout["next", "reward"].sum())
    print(f"TorchRL rollout: {rollout.batch_size[0]} steps, reward {reward:.1f}")

    def act(obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return network(torch.as_tensor(obs, dtype=torch.float32)).numpy()

    print(f"torchrl_rollout: scoring {args.episodes} episodes ...", file=sys.stderr, flush=True)
    result = score(act, args.env, args.n_trailers, name="torchrl-untrained", episodes=args.episodes)
    print(result.markdown)
    return result.summary


if __name__ == "__main__":
    main()
