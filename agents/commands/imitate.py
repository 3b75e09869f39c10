"""``python -m agents.imitate``: DAgger from a planner or trained specialists
(:mod:`agents.training.imitate`).

Limits (checked before anything is built or written; :mod:`agents.artifacts.limits`):

=========================  ==========================================
argument                   bound
=========================  ==========================================
``--episodes``             1 .. 4,096 convoys (one batch)
``--iterations``           1 .. 1,000
``--epochs``               1 .. 10,000
``--validation-episodes``  1 .. 10,000 (seeds from 50,000, short of the selection seeds)
``--expert``               an expert of :data:`agents.policies.experts.EXPERTS`
                           that fits the scene (and the n, and ``--randomize``)
``--planner-samples``      2 .. 1,024 (``mpc`` only)
``--planner-iterations``   1 .. 100 (CEM or iLQR iterations)
``--planner-horizon``      1 .. 200 (``ilqr`` only)
``--expert-policy``        policy specs with ``{n}``, ``COUNTS=`` before all but one
                           (``specialists`` only; ``--teacher`` is the same option)
``--net-arch``             10,000,000 parameters, 64 layers
``--seed``                 training seeds below 2**32
``--n-trailers``           one count N, or a range LOW-HIGH (a generalist)
``--randomize``            a preset of :data:`trailer_env.randomize.PRESETS`
``--observation``          ``flat`` or ``trailers``
``--max-trailers``         the largest n .. 256 (``trailers`` only; default 8)
``--history``              0 .. 64 past frames (``flat`` only)
=========================  ==========================================

The expert (``--expert``): ``mpc`` (the sampling planner; the default on Reverse) or
``ilqr`` (the deterministic iLQR planner; the default on Dock and Coast, which ``mpc``
does not fit). A refused combination (``mpc`` on Dock, ``ilqr`` with a range of n or
randomised parameters, a planner option the expert does not take) exits with status 2
before anything is written. ``specialists`` (any scene, any range of n): trained
policies, one per n (``--expert-policy``, default ``dagger_reverse_v1_n{n}``), label each row
by its own n: policy distillation (:class:`agents.policies.experts.PolicyExpert`). A run
with another expert than the scene's default gets the expert's name at the end of its
default run folder (``..._dagger_s0_ilqr``).

A generalist (``--n-trailers 1-3 --randomize mismatch20``, ``mpc`` only): the env
draws each episode's n and physics; the expert (one planner per n) plans with the
episode's true parameters, the student sees the padded observation and the trailer
mask only.

``--observation trailers``: the student reads the Dict of ``observation="trailers"``
through :class:`~agents.policies.convoy_encoder.ConvoyEncoder`, so it acts with any n up
to ``--max-trailers``; its default run folder ends in ``_trailers``.

``--history K``: the student reads the last K observations and applied actions beside
the current one (``gym.make(..., history=K)``, :mod:`trailer_env.history`): a memory
from which it can tell the convoy's parameters under ``--randomize`` while the expert
plans with the true ones. The card's ``env_kwargs`` record it, so ``agents.evaluate``
rebuilds the window; its default run folder ends in ``_history<K>``.

The run folder and ``--export`` are checked as by ``agents.train`` (writable, no
symbolic link, locked while the run writes it). ``--resume`` first checks every file the
run reads back (:func:`agents.training.imitation_checkpoint.read_saved_run`: the checkpoint, the
record, the data set, the learning curve, the models and their statistics): a damaged
one exits with status 2 naming it, and the folder is left as it was.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from agents.artifacts import limits
from agents.artifacts.run_folder import (
    RunFolderError,
    claimed_run_dir,
    default_run_dir,
    export_model,
    export_problem,
)
from agents.commands import options as cli
from agents.envs import HEADLINE_ENV_ID
from agents.policies.convoy_order import CONVOY_DIRECTIONS
from agents.policies.experts import EXPERTS, default_expert
from agents.policies.sb3 import limit_torch_threads
from agents.seeds import VALIDATION_SEED
from agents.training.imitate import imitate
from agents.training.imitation_checkpoint import CHECKPOINT_FILE, CheckpointError, read_saved_run
from agents.training.imitation_config import MAX_VALIDATION_EPISODES, ImitationConfig
from dynamics.params import MAX_TRAILERS
from trailer_env.observation import OBSERVATIONS

#: The longest ``--planner-horizon`` (twice Dock's default): the iLQR's derivative core
#: holds episodes x (horizon + 1) x (d + 2) rows, at 4,096 convoys and n = 3 9.9M,
#: 2.4 times the sampling planner's largest core (4,096 x 1,024 samples).
MAX_ILQR_HORIZON = 200


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.imitate"), description=(__doc__ or "").split("\n")[0]
    )
    cli.add_env(parser, default=HEADLINE_ENV_ID)
    cli.add_n_trailers(parser, ranges=True)
    cli.add_randomize(
        parser, "randomised physics, a preset (the expert plans with the true parameters)"
    )
    cli.add_seed(parser, 0, "seed of the network, the training episodes and the planner")
    parser.add_argument(
        "--iterations", type=cli.at_least(1, 1000), default=6, help="DAgger iterations (<= 1000)"
    )
    cli.add_episodes(
        parser, 256, "convoys driven per iteration (one batch)", limits.MAX_IMITATION_EPISODES
    )
    parser.add_argument(
        "--epochs",
        type=cli.at_least(1, 10_000),
        default=10,
        help="passes over the data per iteration (<= 10,000)",
    )
    parser.add_argument(
        "--validation-episodes",
        type=cli.at_least(1, MAX_VALIDATION_EPISODES),
        default=ImitationConfig.validation_episodes,
        help="episodes of each iteration's validation, which picks the kept iteration "
        f"(seeds from {VALIDATION_SEED:,}; <= {MAX_VALIDATION_EPISODES:,})",
    )
    parser.add_argument(
        "--net-arch", type=cli.at_least(1), nargs="+", default=None, help="hidden layer sizes"
    )
    parser.add_argument(
        "--expert",
        choices=list(EXPERTS),
        default=None,
        help="the expert that labels: "
        + "; ".join(f"{name}: {expert.summary}" for name, expert in EXPERTS.items())
        + " (default: the scene's first that fits)",
    )
    parser.add_argument(
        "--planner-samples",
        type=cli.at_least(2, 1024),
        default=None,
        help="mpc's candidates per iteration (default 16)",
    )
    parser.add_argument(
        "--planner-iterations",
        type=cli.at_least(1, 100),
        default=None,
        help="the expert's CEM (mpc, default 2) or iLQR (ilqr, default 3) iterations",
    )
    parser.add_argument(
        "--planner-horizon",
        type=cli.at_least(1, MAX_ILQR_HORIZON),
        default=None,
        help="ilqr's planned steps (default the scene's: 60, Dock 100)",
    )
    parser.add_argument(
        "--expert-policy",
        "--teacher",  # the name that committed cards' commands use (agents.reproduce)
        default=None,
        metavar="SPEC",
        help="the expert policies of --expert specialists (also --teacher): a spec with {n} "
        "where the count goes (default dagger_reverse_v1_n{n}), or several, comma-separated, "
        "each but one after its counts: 1-3=ppo_reverse_v1_n{n},dagger_reverse_v1_n{n}; "
        "median(A,B,...) labels with the middle action of those policies",
    )
    parser.add_argument(
        "--observation",
        choices=list(OBSERVATIONS),
        default="flat",
        help="what the student reads: the flat observation, or the Dict of "
        "observation='trailers' through ConvoyEncoder (a GRU along the convoy)",
    )
    parser.add_argument(
        "--max-trailers",
        type=cli.at_least(1, MAX_TRAILERS),
        default=None,
        help="trailer slots of --observation trailers (default 8)",
    )
    parser.add_argument(
        "--convoy-direction",
        choices=list(CONVOY_DIRECTIONS),
        default=CONVOY_DIRECTIONS[0],
        help="the order in which ConvoyEncoder reads the trailers (--observation trailers): "
        "from the cart, from the last trailer, or both passes",
    )
    parser.add_argument(
        "--history",
        type=int,
        default=0,
        metavar="K",
        help="past frames (observation, applied action) the student reads beside the "
        "current observation (gym.make's history=; default 0)",
    )
    parser.add_argument(
        "--mirror",
        action="store_true",
        help="train with the convoy's mirror image: mirrored copies of every "
        "label, a student made odd under it (its card says so)",
    )
    parser.add_argument("--run-dir", type=Path, default=None, help="run folder")
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue the run in the run folder (--run-dir or the default) from its "
        "checkpoint, written after every iteration, to --iterations (the other settings "
        "must be the run's; --overwrite then only replaces --export's files)",
    )
    parser.add_argument(
        "--export", type=Path, default=None, help="copy the best model (+ card, curve) to this .zip"
    )
    cli.add_overwrite(parser, "replace a run in the run folder and --export's files")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    command = ["python", "-m", "agents.imitate", *(sys.argv[1:] if argv is None else argv)]
    if args.net_arch:
        problem = limits.network_problem(args.net_arch)
        if problem is not None:
            parser.error(f"argument --net-arch: {problem}")
    try:
        expert = EXPERTS[args.expert or default_expert(args.env)]
        problem = expert.problem(args.env, args.n_trailers, args.randomize)
        if problem is not None:
            raise ValueError(problem)
        planner = expert.configure(
            samples=args.planner_samples,
            iterations=args.planner_iterations,
            horizon=args.planner_horizon,
            policy=args.expert_policy,
        )
    except (TypeError, ValueError) as error:
        parser.error(f"argument --expert: {error}")
    try:
        config = ImitationConfig(
            env_id=args.env,
            n_trailers=args.n_trailers,
            randomize=args.randomize,
            seed=args.seed,
            iterations=args.iterations,
            episodes=args.episodes,
            epochs=args.epochs,
            validation_episodes=args.validation_episodes,
            net_arch=tuple(args.net_arch) if args.net_arch else None,
            planner=planner,
            expert=expert.name,
            observation=args.observation,
            max_trailers=args.max_trailers,
            mirror=args.mirror,
            convoy_direction=args.convoy_direction,
            history=args.history,
        )
    except (TypeError, ValueError) as error:
        parser.error(str(error))
    if args.export is not None:
        problem = export_problem(args.export, args.overwrite)
        if problem is not None:
            parser.error(f"argument --export: {problem}")
    default = default_run_dir(config.env_id, "dagger", config.run_label, config.seed)  # type: ignore[arg-type]
    if config.randomize is not None:
        default = default.with_name(f"{default.name}_{config.randomize}")
    if config.expert != default_expert(config.env_id):
        default = default.with_name(f"{default.name}_{config.expert}")
    if config.observation != "flat":
        default = default.with_name(f"{default.name}_{config.observation}")
    if config.mirror:
        default = default.with_name(f"{default.name}_mirror")
    if config.history:
        default = default.with_name(f"{default.name}_history{config.history}")
    if config.convoy_direction != CONVOY_DIRECTIONS[0]:
        default = default.with_name(f"{default.name}_{config.convoy_direction}")
    checkpoint = None
    if args.resume:
        checkpoint = (args.run_dir or default) / CHECKPOINT_FILE
        if not checkpoint.is_file():
            parser.error(f"argument --resume: no checkpoint {checkpoint}")
        try:  # the whole folder, before anything is written (the model: once built)
            read_saved_run(checkpoint.parent)
        except CheckpointError as error:
            parser.error(f"argument --resume: {error}")
    try:
        with claimed_run_dir(
            default, args.run_dir, resume=checkpoint, overwrite=args.overwrite
        ) as run_dir:
            limit_torch_threads()
            imitate(config, run_dir, resume=args.resume, command=command)
            if args.export is not None:
                print(f"exported {export_model(run_dir, args.export, overwrite=args.overwrite)}")
    except RunFolderError as error:
        parser.error(f"argument --run-dir: {error}")
    except CheckpointError as error:
        parser.error(f"argument --resume: {error}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
