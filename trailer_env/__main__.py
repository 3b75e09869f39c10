"""``python -m trailer_env``: list the environments, or play one from the keyboard.

    python -m trailer_env                              # one line per registered id
    python -m trailer_env --play trailer_env/Reverse-v1 --n-trailers 1
    python -m trailer_env --compile                    # compile the kernels (install does)
    python -m trailer_env --keywords docs/generated/keywords.md   # the gym.make keywords

Playing needs a display and pygame (``pip install 'trailer-env[rendering]'``; without
either it exits 2 saying which is missing, before opening anything); the keys
are the env's ``get_keys_to_action()`` (``a``/``d`` move the mass left/right).
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

import trailer_env
from trailer_env.benchmark import write_atomic
from trailer_env.settings import keywords_markdown


def registered_ids() -> list[str]:
    """The ids ``import trailer_env`` registers, in registration order."""
    return [env_id for env_id in gym.registry if env_id.startswith("trailer_env/")]


def summary(env_id: str) -> str:
    """One line: id, episode length and the first line of the env's docstring."""
    spec = gym.spec(env_id)
    creator = gym.envs.registration.load_env_creator(str(spec.entry_point))
    doc = (creator.__doc__ or "").strip().splitlines()
    return f"{env_id:<26} {spec.max_episode_steps:>4} steps  {doc[0] if doc else ''}"


def play_problem() -> str:
    """Why a keyboard session cannot open here ("" when it can): pygame and a display."""
    if importlib.util.find_spec("pygame") is None:
        return "needs pygame: pip install 'trailer-env[rendering]'"
    headless = os.environ.get("SDL_VIDEODRIVER", "") in ("dummy", "offscreen")
    if headless or not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return "needs a display (DISPLAY or WAYLAND_DISPLAY is unset, or SDL_VIDEODRIVER=dummy)"
    return ""


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    description = (__doc__ or "").splitlines()[0]
    script = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else ""
    # The usage line names what is running: the console script, or the module.
    prog = script if script == "trailer-env" else "python -m trailer_env"
    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument("--play", metavar="ID", help="drive this environment from the keyboard")
    parser.add_argument("--n-trailers", type=int, default=2, help="trailers when playing")
    parser.add_argument("--seed", type=int, default=None, help="seed of the first episode")
    parser.add_argument(
        "--compile",
        action="store_true",
        help="compile every kernel now (numba's disk cache), so that no first run waits",
    )
    parser.add_argument(
        "--keywords",
        metavar="PATH",
        type=Path,
        help="write the table of gym.make's keywords (Markdown) to PATH",
    )
    args = parser.parse_args(argv)
    if args.keywords is not None and not args.keywords.parent.is_dir():
        parser.error(f"argument --keywords: no folder {args.keywords.parent}")
    print(f"trailer-env {trailer_env.__version__}")
    if args.keywords is not None:
        write_atomic(args.keywords, keywords_markdown())
        print(f"wrote {args.keywords}")
        return 0
    if args.compile:
        from trailer_env.warmup import compile_kernels

        print(f"compiled every kernel in {compile_kernels():.0f} s")
        return 0
    if args.play is None:
        for env_id in registered_ids():
            print(summary(env_id))
        return 0
    if args.play not in registered_ids():
        parser.error(f"unknown environment {args.play!r}; choose from {registered_ids()}")
    if args.seed is not None and not 0 <= args.seed < 2**32:
        parser.error(f"argument --seed: must be in 0..2**32 - 1, got {args.seed}")
    try:
        env = gym.make(args.play, render_mode="rgb_array", n_trailers=args.n_trailers)
    except (TypeError, ValueError) as error:
        parser.error(f"argument --n-trailers: {error}")
    problem = play_problem()
    if problem:
        env.close()
        parser.error(f"argument --play: {problem}")
    from gymnasium.utils.play import play

    noop = np.zeros(env.action_space.shape or (1,), dtype=np.float32)
    play(env, fps=env.metadata["render_fps"], noop=noop, seed=args.seed)
    return 0


if __name__ == "__main__":
    sys.exit(main())
