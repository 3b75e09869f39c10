"""Ray RLlib as its users write it: a plain ``PPOConfig`` on a trailer_env id, then the score.

    python examples/rllib_ppo.py --iterations 5

The id is given as ``"trailer_env:trailer_env/Reverse-v1"``: Gymnasium imports the
module before the id is looked up, so every env runner (a separate process, maybe on
another node) registers the scenes itself. The trained RLModule then acts on the
native batch through :func:`trailer_env.benchmark.score`. Needs the ``rllib`` extra.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import ray
import torch
from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core.columns import Columns

from trailer_env.benchmark import score

ENV = "trailer_env:trailer_env/Reverse-v1"


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n-trailers", type=int, default=1)
    parser.add_argument("--iterations", type=int, default=5)
    parser.add_argument("--episodes", type=int, default=100)
    args = parser.parse_args(argv)
    print("rllib_ppo: starting a local Ray and one env runner ...", file=sys.stderr, flush=True)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        config = (
            PPOConfig()
            .environment(ENV, env_config={"n_trailers": args.n_trailers})
            .env_runners(num_env_runners=1, num_envs_per_env_runner=8)
            .training(train_batch_size_per_learner=2048, minibatch_size=256)
        )
        algorithm = config.build_algo()
        for iteration in range(args.iterations):
            result = algorithm.train()
            print(f"iteration {iteration + 1}: {result['num_env_steps_sampled_lifetime']} steps")
        module = algorithm.get_module()

        def act(obs: np.ndarray) -> np.ndarray:
            with torch.no_grad():
                output = module.forward_inference({Columns.OBS: torch.as_tensor(obs).float()})
            return np.clip(output[Columns.ACTION_DIST_INPUTS].numpy()[:, :1], -1.0, 1.0)

        print(f"rllib_ppo: scoring {args.episodes} episodes ...", file=sys.stderr, flush=True)
        summary = score(
            act, ENV.partition(":")[2], args.n_trailers, name="rllib-ppo", episodes=args.episodes
        )
        print(summary.markdown)
        algorithm.stop()
        return summary.summary
    finally:
        ray.shutdown()


if __name__ == "__main__":
    main()
