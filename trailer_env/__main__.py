"""``python -m trailer_env``: list the environments, or play one from the keyboard.

    python -m trailer_env                              # one line per registered id
    python -m trailer_env --play trailer_env/Reverse-v0 --n-trailers 1

Playing needs a display and pygame (``pip install 'trailer-env[rendering]'``); the keys
are the env's ``get_keys_to_action()`` (``a``/``d`` move the mass left/right).
"""

from __future__ import annotations

import argparse
import sys

import gymnasium as gym
import numpy as np

import trailer_env


def registered_ids() -> list[str]:
    """The ids ``import trailer_env`` registers, in registration order."""
    return [env_id for env_id in gym.registry if env_id.startswith("trailer_env/")]


def summary(env_id: str) -> str:
    """One line: id, episode length and the first line of the env's docstring."""
    spec = gym.spec(env_id)
    creator = gym.envs.registration.load_env_creator(str(spec.entry_point))
    doc = (creator.__doc__ or "").strip().splitlines()
    return f"{env_id:<26} {spec.max_episode_steps:>4} steps  {doc[0] if doc else ''}"


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    description = (__doc__ or "").splitlines()[0]
    parser = argparse.ArgumentParser(prog="python -m trailer_env", description=description)
    parser.add_argument("--play", metavar="ID", help="drive this environment from the keyboard")
    parser.add_argument("--n-trailers", type=int, default=2, help="trailers when playing")
    parser.add_argument("--seed", type=int, default=None, help="seed of the first episode")
    args = parser.parse_args(argv)
    print(f"trailer-env {trailer_env.__version__}")
    if args.play is None:
        for env_id in registered_ids():
            print(summary(env_id))
        return 0
    if args.play not in registered_ids():
        parser.error(f"unknown environment {args.play!r}; choose from {registered_ids()}")
    from gymnasium.utils.play import play

    env = gym.make(args.play, render_mode="rgb_array", n_trailers=args.n_trailers)
    noop = np.zeros(env.action_space.shape or (1,), dtype=np.float32)
    play(env, fps=env.metadata["render_fps"], noop=noop, seed=args.seed)
    return 0


if __name__ == "__main__":
    sys.exit(main())
