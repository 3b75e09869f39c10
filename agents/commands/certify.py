"""``python -m agents.certify``: certify a scene's ceiling (:mod:`agents.certification.certify`).

Limits (checked before any start is screened; :mod:`agents.artifacts.limits`):

====================  ===================================================
argument              bound
====================  ===================================================
``--seeds``           10,000 seeds at most, each in 0 .. 2**32 - 1
``--n-trailers``      the environment's (0 .. 256)
``--samples``         2 .. 1,024 candidates per start
``--iterations``      1 .. 100
``--restarts``        0 .. 100
``--planner``         the planner of the scene's objective: mpc (survival:
                      Reverse) or ilqr (goal: Dock, Coast); the other is refused
``--closed-loop``     dopri5 (goal scenes only)
``--jacobians``       exact (default) or differences (goal scenes only)
``--randomize``       a preset (mismatch10 .. mismatch40) or a JSON object of
                      factor ranges; survival scenes only
====================  ===================================================

``--randomize PRESET_OR_JSON`` certifies randomised physics (:mod:`trailer_env.randomize`):
each start's parameters are drawn from its seed as ``gym.make(..., randomize=...)``
draws them, and the screen, the planner, the witnesses and the replays use them. The
default witnesses then include ``lqr-adaptive``. Refused for the goal scenes (iLQR).

``--witnesses SPEC ...`` (default: the scene's baselines and every committed model of
that env and n) are then tried on the starts the planner leaves open, and a record of
theirs that replays to success makes the start feasible with that ``source``
(:mod:`agents.certification.witnesses`); ``--no-witnesses`` keeps the planner's records
only. ``--from-certificate PATH`` skips the planner and adds witnesses to an existing
certificate (its records beside it). ``--witness-samples K`` then plays every model
witness K more times on each start still open, its actions sampled from its
distribution (``--sample-seed``): a stochastic policy's lucky episode is as good a
record as any once it replays. ``--warm-start [SPEC ...]`` (goal scenes) then plans
the starts still open with iLQR from the states those policies reach.

``--out`` (default ``out/certify/<scene>_n<n>``, :func:`default_out`) must be a
writable folder; an existing one is written into only with
``--overwrite``, which replaces the certificate's own files (certificate.json,
certificate.md, actions/seed_*.npy) and nothing else; a link among them is refused.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Mapping
from pathlib import Path

from agents.artifacts import files, limits
from agents.artifacts.action_records import read_actions
from agents.artifacts.certificates import (
    CertificateEnv,
    Certified,
    markdown,
    read_certificate,
    records_beside,
    write_certificate,
    write_problem,
)
from agents.certification.certify import (
    PLANNERS,
    certify,
    certifying_planner,
    planner_problem,
    randomize_kwarg,
)
from agents.certification.replays import check_records
from agents.certification.search import CLOSED_LOOP_INTEGRATORS
from agents.certification.warm_start import repeated_labels, warm_start
from agents.certification.witnesses import (
    MAX_WITNESS_SAMPLES,
    add_witnesses,
    committed_witnesses,
    default_witnesses,
)
from agents.commands import options as cli
from agents.envs import (
    ENV_IDS,
    HEADLINE_ENV_ID,
    HEADLINE_N_TRAILERS,
    MakeKwargs,
    check_env_id,
    env_settings,
    scene_of,
)
from agents.oracles.ilqr import JACOBIANS, ILQRConfig
from agents.oracles.planner import PlannerConfig
from agents.policies.registry import load_policy, window_kwargs
from trailer_env.randomize import PRESETS

#: The defaults of --env, --n-trailers and --seeds.
DEFAULT_ENV, DEFAULT_N, DEFAULT_SEEDS = HEADLINE_ENV_ID, HEADLINE_N_TRAILERS, "1000-1099"
#: The folder the default ``--out`` lies in.
DEFAULT_OUT_ROOT = Path("out") / "certify"

#: ``--randomize``'s value: a preset's name or factor ranges.
RandomizeValue = str | Mapping[str, object]


def default_out(
    env_id: str, n_trailers: int, randomize: RandomizeValue | None, witnessed: bool
) -> Path:
    """``--out``'s default: ``out/certify/<scene>[_<preset>]_n<n>`` (the committed
    certificates' names, :func:`agents.artifacts.certificates.certificate_path`; custom
    factor ranges read ``randomized``), ending in ``_witnessed`` for ``--from-certificate``,
    so that the documented commands run one after another each write their own folder."""
    physics = (
        ""
        if randomize is None
        else "_" + (randomize if isinstance(randomize, str) else "randomized")
    )
    name = f"{scene_of(env_id)}{physics}_n{n_trailers}" + ("_witnessed" if witnessed else "")
    return DEFAULT_OUT_ROOT / name


def parse_seeds(text: str, maximum: int = limits.MAX_CERTIFY_SEEDS) -> list[int]:
    """ "1000-1099" -> [1000, ..., 1099]; "5" -> [5]; "1,4,9" -> [1, 4, 9]
    (:func:`agents.commands.options.integer_list`).

    Raises:
        ValueError: On no seeds at all (an empty text); a malformed, empty or repeated
            seed, one outside 0 .. 2**32 - 1, or more than ``maximum`` seeds (counted
            before any list is built).
    """
    return cli.integer_list(text, 0, limits.MAX_SEED, max_count=maximum)


def randomize_value(text: str) -> RandomizeValue:
    """``--randomize``: a preset name, or a JSON object of factor ranges (checked later
    against the scene, :func:`agents.certification.certify.randomize_kwarg`)."""
    if text in PRESETS:
        return text
    depth = files.json_depth(text.encode("utf-8", "surrogateescape"))
    if depth > files.MAX_JSON_DEPTH:  # json.loads would end in a RecursionError
        raise argparse.ArgumentTypeError(
            f"the value is nested {depth} deep, over the limit of {files.MAX_JSON_DEPTH}"
        )
    try:
        value = json.loads(text) if text.lstrip().startswith("{") else None
    except json.JSONDecodeError:
        value = None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(
            f"expected a preset ({', '.join(sorted(PRESETS))}) or a JSON object of factor "
            f"ranges such as '{{\"mu\": [0.8, 1.2]}}', got {text[:40]!r}"
        )
    return value


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.certify"), description="Certify a scene's ceiling over seeds."
    )
    _add_scene_options(parser)
    _add_planner_options(parser)
    _add_witness_options(parser)
    parser.set_defaults(env=None, n_trailers=None, seeds=None)
    return parser


def _add_scene_options(parser: argparse.ArgumentParser) -> None:
    """--env, --n-trailers, --seeds, --randomize, --out and --overwrite."""
    parser.add_argument(
        "--env",
        default=DEFAULT_ENV,
        choices=ENV_IDS,
        metavar="ENV_ID",
        help=f"one of {', '.join(ENV_IDS)}",
    )
    cli.add_n_trailers(parser, DEFAULT_N)
    parser.add_argument(
        "--seeds",
        default=DEFAULT_SEEDS,
        help=f"e.g. 1000-1099 (default) or 1,4,9; at most {limits.MAX_CERTIFY_SEEDS:,} seeds",
    )
    parser.add_argument(
        "--randomize",
        type=randomize_value,
        default=None,
        metavar="PRESET_OR_JSON",
        help=f"randomised physics: a preset ({', '.join(sorted(PRESETS))}) or a JSON object "
        "of factor ranges; each start's drawn parameters are planned with and replayed "
        "(survival scenes only)",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="output folder (default out/certify/<scene>_n<n>, e.g. out/certify/reverse_v1_n2; "
        "with --randomize out/certify/<scene>_<preset>_n<n>; with --from-certificate "
        "the same name ending in _witnessed)",
    )
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out")


def _add_planner_options(parser: argparse.ArgumentParser) -> None:
    """--planner, --closed-loop, --samples, --iterations and --restarts."""
    parser.add_argument(
        "--planner",
        choices=tuple(PLANNERS),
        default=None,
        help="the planner of the scene's objective, the default: mpc (the sampling planner) "
        "certifies the survival scenes, ilqr the goal scenes (by reaching their goal)",
    )
    parser.add_argument(
        "--closed-loop",
        choices=CLOSED_LOOP_INTEGRATORS,
        default=None,
        help="goal scenes: also re-plan every start on a plant with this integrator "
        "(rtol = atol = 1e-8) and record whether it still reaches the goal",
    )
    parser.add_argument(
        "--jacobians",
        choices=JACOBIANS,
        default=None,
        help="ilqr: the step's Jacobians exact (autograd through the differentiable twin, "
        "the default: fewer starts left open) or by finite differences of the kernel",
    )
    parser.add_argument(
        "--samples",
        type=cli.at_least(2, 1024),
        default=PlannerConfig.samples,
        help=f"planner candidates per start (default {PlannerConfig.samples}, at most 1024)",
    )
    parser.add_argument(
        "--iterations",
        type=cli.at_least(1, 100),
        default=None,
        help=f"planner iterations: CEM (mpc, default {PlannerConfig.iterations}) or iLQR "
        f"(ilqr, default {ILQRConfig.iterations}); at most 100",
    )
    parser.add_argument(
        "--restarts",
        type=cli.at_least(0, 100),
        default=None,
        help="plan the starts not kept safe (mpc: with new planner seeds, default "
        f"{PLANNERS['mpc'].restarts}) or not at the goal (ilqr: longer horizon, more "
        f"iterations, default {PLANNERS['ilqr'].restarts}; --warm-start: default 1) again, "
        "up to this many times",
    )


def _add_witness_options(parser: argparse.ArgumentParser) -> None:
    """The witnesses group: --witnesses, --no-witnesses, --from-certificate, --warm-start,
    --witness-samples and --sample-seed."""
    witnesses = parser.add_argument_group(
        "witnesses", "other sources of action records (agents.certification.witnesses)"
    )
    witnesses.add_argument(
        "--witnesses",
        nargs="+",
        metavar="SPEC",
        default=None,
        help="policies tried on the starts the planner leaves open (a baseline name, a "
        "committed model's stem, a model path); default: the scene's baselines and every "
        "committed model (agents/models, agents/models/seeds) of this env and n",
    )
    witnesses.add_argument("--no-witnesses", action="store_true", help="the planner's records only")
    witnesses.add_argument(
        "--from-certificate",
        type=Path,
        default=None,
        metavar="PATH",
        help="add witnesses to this certificate (a certificate.json beside its actions.npz, "
        "or a committed <scene>_n<n>.json beside <scene>_n<n>_actions.npz) instead of "
        "running the planner; --env, --n-trailers and --seeds are the certificate's",
    )
    witnesses.add_argument(
        "--warm-start",
        nargs="*",
        metavar="SPEC",
        default=None,
        help="goal scenes: then plan the starts still open with iLQR from states these "
        "policies reach (default when given bare: every committed model of this env and n)",
    )
    witnesses.add_argument(
        "--witness-samples",
        type=cli.bounded(0, MAX_WITNESS_SAMPLES),
        default=0,
        metavar="K",
        help="then play every model witness K times more on each start still open, its "
        "actions sampled from its distribution (seeded by --sample-seed); default 0, at "
        f"most {MAX_WITNESS_SAMPLES}",
    )
    witnesses.add_argument(
        "--sample-seed",
        type=cli.seed_value,
        default=0,
        help="seed of --witness-samples' draws (default 0)",
    )


def load_certificate(path: Path) -> Certified:
    """A certificate file and its action records, checked and replayed.

    The records are replayed on the certificate's own scene, n and physics
    (:func:`agents.certification.replays.check_records`) before anything is built on
    them: a record that does not replay to its start's stated outcome is refused.

    Raises:
        ValueError: If either file is missing or invalid, the env or its settings are
            unknown, a feasible start has no record, a start that is not feasible has
            one, or a record does not replay to its start's stated outcome (the message
            names the start).
    """
    certificate = read_certificate(path)
    check_env_id(certificate.env_id)
    try:
        env_settings(certificate.env_kwargs.kwargs())
    except (TypeError, ValueError) as error:
        raise ValueError(f"{path}: env_kwargs: {error}") from None
    records_path = records_beside(path)
    if not records_path.is_file():
        raise ValueError(f"{path}: its action records {records_path} are missing")
    loaded = Certified(certificate, read_actions(records_path))
    check_records(loaded, str(path))
    return loaded


def _base(parser: argparse.ArgumentParser, args: argparse.Namespace) -> Certified | None:
    """``--from-certificate``'s certificate (None without it); its env and n become
    ``args.env`` and ``args.n_trailers`` (exits 2 when the given ones differ)."""
    if args.from_certificate is None:
        return None
    if args.seeds is not None:
        parser.error("argument --seeds: not with --from-certificate (its seeds are kept)")
    try:
        base = load_certificate(args.from_certificate)
    except (OSError, ValueError) as error:
        parser.error(f"argument --from-certificate: {error}")
    kept_env, kept_n = base.certificate.env_id, base.certificate.n_trailers
    for given, key, value in (
        (args.env, "--env", kept_env),
        (args.n_trailers, "--n-trailers", kept_n),
    ):
        if given is not None and given != value:
            parser.error(f"argument {key}: {given} is not the certificate's {value}")
    args.env, args.n_trailers = kept_env, kept_n
    return base


def _physics(
    parser: argparse.ArgumentParser,
    args: argparse.Namespace,
    env_id: str,
    base: Certified | None,
) -> CertificateEnv:
    """The ``gym.make`` keywords of the certificate: ``n_trailers`` and, with
    ``--randomize`` (or a randomised ``--from-certificate``), ``randomize``."""
    n_trailers = DEFAULT_N if args.n_trailers is None else args.n_trailers
    try:
        env_settings({"n_trailers": n_trailers})
    except (TypeError, ValueError) as error:
        parser.error(f"argument --n-trailers: {error}")
    randomize: RandomizeValue | None = None
    if args.randomize is not None:
        try:
            randomize = randomize_kwarg(env_id, args.randomize)
            env_settings({"n_trailers": n_trailers, "randomize": randomize})
        except (TypeError, ValueError) as error:
            parser.error(f"argument --randomize: {error}")
    if base is not None:
        given = base.certificate.env_kwargs.randomize
        kept = given if given is None or isinstance(given, str) else dict(given)
        if args.randomize is not None and randomize != kept:
            parser.error(f"argument --randomize: {randomize!r} is not the certificate's {kept!r}")
        randomize = kept
    return CertificateEnv(n_trailers=n_trailers, randomize=randomize)


def _witness_specs(
    parser: argparse.ArgumentParser,
    args: argparse.Namespace,
    env_id: str,
    environment: CertificateEnv,
    base: Certified | None,
) -> tuple[list[str], list[str]]:
    """The witnesses' and the warm start's policy specs (defaults filled in); exits 2 on
    options that do not go together."""
    if args.no_witnesses and (args.witnesses is not None or args.warm_start is not None):
        parser.error("argument --no-witnesses: not with --witnesses or --warm-start")
    if args.no_witnesses and args.witness_samples:
        parser.error("argument --no-witnesses: not with --witness-samples")
    if args.no_witnesses and base is not None:
        parser.error("argument --no-witnesses: --from-certificate only adds witnesses")
    if args.warm_start is not None and not _certified_by_ilqr(env_id):
        parser.error(f"argument --warm-start: goal scenes only (iLQR), not {env_id}")
    n_trailers = environment.n_trailers
    specs = [] if args.no_witnesses else args.witnesses
    if specs is None:
        randomized = environment.randomize is not None
        specs = default_witnesses(env_id, n_trailers, randomized=randomized)
    warm = args.warm_start or []
    if args.warm_start == []:
        warm = [str(path) for path in committed_witnesses(env_id, n_trailers)]
    return specs, warm


def _certified_by_ilqr(env_id: str) -> bool:
    try:
        return certifying_planner(env_id) == "ilqr"
    except ValueError:
        return False


#: iLQR's Jacobians when certifying (``--jacobians``): exact, which left 11 of the 400
#: goal starts open where differences left 32 (benchmarks/results/ilqr_jacobians.md).
CERTIFY_JACOBIANS = "exact"


def _planner_config(
    parser: argparse.ArgumentParser, args: argparse.Namespace, env_id: str
) -> PlannerConfig | ILQRConfig:
    """The settings of the planner that certifies ``env_id``; exits 2 when ``--planner``
    or ``--closed-loop`` do not fit the scene."""
    problem = planner_problem(env_id, args.planner)
    if problem is not None:
        parser.error(f"argument --planner: {problem}")
    goal = certifying_planner(env_id) == "ilqr"
    if args.closed_loop is not None and not goal:
        parser.error(f"argument --closed-loop: only for the goal scenes, not {env_id}")
    if args.jacobians is not None and not goal:
        parser.error(f"argument --jacobians: only for ilqr (the goal scenes), not {env_id}")
    try:
        if goal:
            iterations = ILQRConfig.iterations if args.iterations is None else args.iterations
            jacobians = CERTIFY_JACOBIANS if args.jacobians is None else args.jacobians
            return ILQRConfig(iterations=iterations, jacobians=jacobians)
        return PlannerConfig(
            samples=args.samples,
            iterations=PlannerConfig.iterations if args.iterations is None else args.iterations,
            elites=min(PlannerConfig.elites, max(1, args.samples // 4)),
        )
    except ValueError as error:
        parser.error(str(error))


def _check_policies(
    parser: argparse.ArgumentParser,
    specs: list[str],
    warm: list[str],
    env_id: str,
    env_kwargs: MakeKwargs,
) -> None:
    """Exits 2 unless every witness and warm-start spec loads for the env."""
    repeated = repeated_labels(warm)
    if repeated:
        parser.error(f"argument --warm-start: two specs of one label: {repeated}")
    for spec in [*specs, *warm]:
        try:
            load_policy(spec, env_id, window_kwargs(spec, env_kwargs))
        except (OSError, ValueError) as error:
            parser.error(f"argument --witnesses: {error}")


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    base = _base(parser, args)
    env_id = check_env_id(args.env or DEFAULT_ENV)
    environment = _physics(parser, args, env_id, base)
    try:
        seeds = parse_seeds(DEFAULT_SEEDS if args.seeds is None else args.seeds)
    except ValueError as error:
        parser.error(f"argument --seeds: {error}")
    specs, warm = _witness_specs(parser, args, env_id, environment, base)
    config = _planner_config(parser, args, env_id)
    n_trailers, randomize = environment.n_trailers, environment.randomize
    if args.out is None:
        args.out = default_out(env_id, n_trailers, randomize, witnessed=base is not None)
    problem = write_problem(args.out, args.overwrite)
    if problem is not None:
        parser.error(f"argument --out: {problem}")
    _check_policies(parser, specs, warm, env_id, environment.kwargs())
    certified = base or certify(
        env_id,
        n_trailers,
        seeds,
        config,
        args.restarts,
        randomize=randomize,
        closed_loop=args.closed_loop,
    )
    if specs:
        certified = add_witnesses(
            certified, specs, samples=args.witness_samples, sample_seed=args.sample_seed
        )
    if warm:
        warm_restarts = 1 if args.restarts is None else args.restarts
        ilqr_config = config if isinstance(config, ILQRConfig) else None
        certified = warm_start(certified, warm, config=ilqr_config, restarts=warm_restarts)
    written = write_certificate(certified, args.out, args.overwrite)
    print(markdown(written).split("\n\n| seed")[0])
    print(f"wrote {args.out / 'certificate.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
