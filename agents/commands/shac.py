"""``python -m agents.shac``: train a policy by SHAC, backpropagating short rollouts through
the exact model (:mod:`agents.training.shac`).

Usage::

    python -m agents.shac --env trailer_env/Reverse-v1 --n-trailers 2 --seed 0 \\
        --iterations 200 [--horizon 32] [--num-envs 64] [--init-from MODEL --critic-warmup 20] \\
        [--actor-lr 1e-4] [--gamma 0.999] [--log-std-init -1.5] [--state-gradient-clip 1] \\
        [--action-bound-weight 10] [--target-critic 0.2] [--anneal] [--run-dir DIR] [--overwrite]

Writes the run folder (default ``runs/<scene>_n<n>_shac_s<seed>``): ``config.json``,
``evaluations.csv``, ``best_model.zip`` and ``final_model.zip`` with their cards and
statistics; ``python -m agents.evaluate --policy <run>/best_model.zip`` evaluates it. An
existing run folder is replaced only with ``--overwrite``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from agents.artifacts.run_folder import RunFolderError, claimed_run_dir, default_run_dir
from agents.commands import options as cli
from agents.envs import HEADLINE_ENV_ID
from agents.training.shac import SHACConfig, train_shac

#: The real-valued settings, one option each (``--actor-lr`` sets ``actor_lr``), checked
#: by :class:`SHACConfig`.
REAL_OPTIONS = (
    ("actor_lr", "the actor's Adam step size"),
    ("gamma", "discount of the window's return"),
    ("log_std_init", "the actor's log standard deviation at the start (also after --init-from)"),
    (
        "state_gradient_clip",
        "each convoy's backward gradient is scaled to at most this norm at every step "
        "(0: not clipped)",
    ),
    (
        "action_bound_weight",
        "weight of the pull keeping the mean action within its bounds (0: none)",
    ),
    (
        "target_critic",
        "bootstrap from a target critic that keeps this share of itself per window "
        "(0: the critic; SHAC's is 0.2)",
    ),
)


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.shac"),
        description="Train a policy by SHAC through the differentiable twin",
    )
    cli.add_env(parser, HEADLINE_ENV_ID)
    parser.add_argument("--n-trailers", type=cli.at_least(1, 64), default=SHACConfig.n_trailers)
    cli.add_seed(parser, 0, "the run's seed")
    parser.add_argument(
        "--iterations", type=cli.at_least(1, 1_000_000), default=SHACConfig.iterations
    )
    parser.add_argument("--horizon", type=cli.at_least(1, 1024), default=SHACConfig.horizon)
    parser.add_argument("--num-envs", type=cli.at_least(2, 4096), default=SHACConfig.num_envs)
    parser.add_argument(
        "--eval-every", type=cli.at_least(1, 1_000_000), default=SHACConfig.eval_every
    )
    parser.add_argument(
        "--validation-episodes",
        type=cli.at_least(1, 10_000),
        default=SHACConfig.validation_episodes,
        help="episodes of each validation (seeds from the validation seed)",
    )
    parser.add_argument(
        "--init-from",
        type=Path,
        default=None,
        metavar="MODEL",
        help="start from this PPO model's weights and statistics (e.g. an imitated policy's "
        "zip, agents/models/dagger_reverse_v1_n4.zip)",
    )
    parser.add_argument(
        "--critic-warmup",
        type=cli.at_least(0, 1_000_000),
        default=SHACConfig.critic_warmup,
        help="iterations that fit the critic only, first",
    )
    for name, help_text in REAL_OPTIONS:
        parser.add_argument(
            f"--{name.replace('_', '-')}",
            type=float,
            default=getattr(SHACConfig, name),
            help=help_text,
        )
    parser.add_argument(
        "--anneal", action="store_true", help="step sizes fall linearly to 0 over the run"
    )
    parser.add_argument("--run-dir", type=Path, default=None, help="run folder")
    cli.add_overwrite(parser, "replace an existing run folder")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        config = SHACConfig(
            env_id=args.env,
            n_trailers=args.n_trailers,
            seed=args.seed,
            iterations=args.iterations,
            horizon=args.horizon,
            num_envs=args.num_envs,
            eval_every=args.eval_every,
            validation_episodes=args.validation_episodes,
            init_from=None if args.init_from is None else str(args.init_from),
            critic_warmup=args.critic_warmup,
            anneal=args.anneal,
            **{name: getattr(args, name) for name, _ in REAL_OPTIONS},
        )
    except (TypeError, ValueError) as error:
        parser.error(str(error))
    default = default_run_dir(config.env_id, "shac", config.n_trailers, config.seed)
    command = ["python", "-m", "agents.shac", *(sys.argv[1:] if argv is None else argv)]
    try:
        with claimed_run_dir(default, args.run_dir, overwrite=args.overwrite) as run_dir:
            train_shac(config, run_dir, command=command)
    except RunFolderError as error:
        parser.error(f"argument --run-dir: {error}")
    print(f"wrote {run_dir}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
