"""Evaluate policies (baselines by name, saved models by path) over K seeded episodes.

Usage::

    python -m agents.evaluate --env trailer_env/Reverse-v1 --n-trailers 2 \
        --policy zero lqr dagger_reverse_v1_n2 my_policy:act --episodes 100

A policy is a baseline name, the stem of a shipped model (``dagger_reverse_v1_n2`` is
the installed package's ``agents/models/dagger_reverse_v1_n2.zip``, from any folder), a
model zip's path, an RLlib checkpoint folder (``runs/<run>/checkpoint``) or
``module:name``, a batched callable of your own (observations (K, obs_dim) -> actions,
imported from the working folder; the episodes are the benchmark protocol's,
:mod:`trailer_env.benchmark`). Model files are
loaded without unpickling anything unless ``--trust-pickle``
(:mod:`agents.artifacts`), and a model whose card names another environment id or
number of trailers is refused unless ``--force``; without ``--env`` (``--n-trailers``) the
first model's card names them (else Reverse-v1, n = 2), and a model with a memory
(``history=k`` on its card, :mod:`trailer_env.history`) gives the env its window unless
``--set history=`` does; the other policies then read the window's current frame.
``--video PATH.mp4|.gif`` also writes every frame of one episode (seed ``--seed``) of
the first policy.

Without ``--policy`` it evaluates the scene's baselines and every committed model
(``agents/models/*.zip``) trained for that environment and number of trailers.
All episodes of one policy run in one native batch; episode ``i`` is seeded
``seed + i`` (default seed 1000), so the same command gives the same JSON.

Writes to ``--out`` (default ``out/evaluate/<scene>_n<n>`` followed by the
``--policy`` names and the ``--set`` settings, :func:`default_out`): ``results.json``
(every metric, per policy), ``results.md`` (a Markdown table, also printed), and
unless ``--no-plots``: ``margins.png`` (singular-margin histograms), ``frames.png`` (a
rendered episode per policy) and ``curves.png`` (learning curves of the models that have
them), each atomically.
Everything is checked before the first episode: ``--out`` and ``--video`` must be
writable and no symbolic link (nor any of the files written in ``--out``), none of
the files it would write may exist unless ``--overwrite`` (``results.json`` and
``results.md``, and the three pictures unless ``--no-plots``), the
episodes' seeds must stay below 2**32 and ``--episodes`` at most 100,000
(:mod:`agents.artifacts.limits`); every model, card, statistics file and learning
curve is loaded and checked first.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Mapping
from pathlib import Path

from agents.artifacts import files
from agents.artifacts.shipped import committed_models
from agents.commands import options as cli
from agents.envs import ENV_IDS, HEADLINE_ENV_ID, check_env_id, env_settings, scene_of
from agents.evaluation.pictures import write_pictures
from agents.evaluation.results import (
    curve_metric,
    default_baselines,
    evaluate_policies,
    results_document,
)
from agents.evaluation.tables import markdown_table, table_legend
from agents.policies.baselines import BASELINES
from agents.policies.registry import is_model_spec, model_card, policy_label
from agents.policies.sb3 import limit_torch_threads
from agents.progress import plural
from agents.seeds import TEST_SEED

#: The files written to --out.
OUT_FILES = ("results.json", "results.md", "margins.png", "frames.png", "curves.png")


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.evaluate"),
        description="Evaluate baselines and saved agents over seeded episodes.",
    )
    # Without them, the first --policy model's card names the scene (the model was
    # trained there; anything else would be refused without --force).
    parser.add_argument(
        "--env",
        default=None,
        choices=ENV_IDS,
        metavar="ENV_ID",
        help=f"environment id, one of {', '.join(ENV_IDS)} (default: the first --policy "
        f"model's card, else {HEADLINE_ENV_ID})",
    )
    parser.add_argument(
        "--n-trailers",
        type=cli.at_least(0),
        default=None,
        help="number of trailers (default: the first --policy model's card, else 2)",
    )
    cli.add_env_kwargs(parser)
    parser.add_argument(
        "--policy",
        nargs="+",
        default=None,
        metavar="POLICY",
        help=f"baselines ({', '.join(BASELINES)}), shipped models by stem "
        "(e.g. dagger_reverse_v1_n2), model paths (.zip), RLlib checkpoint folders and/or "
        "module:name, a batched callable of your own (imported from the working folder); "
        "median(A,B,...) for the middle action of those, +mirror after any to make it odd; "
        "default: the scene's baselines and its committed models",
    )
    cli.add_episodes(parser, 100, "episodes (default 100)")
    cli.add_seed(parser, TEST_SEED, f"episode i is seeded seed + i (default {TEST_SEED})")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="output folder (default out/evaluate/<scene>_n<n>, then the --policy names and "
        "the --set settings: e.g. out/evaluate/reverse_v1_n2_lqr_dagger_reverse_v1_n2)",
    )
    parser.add_argument("--no-plots", action="store_true", help="write JSON and Markdown only")
    parser.add_argument(
        "--video",
        type=Path,
        default=None,
        metavar="PATH.mp4|PATH.gif",
        help="also write a video of one episode (seed --seed) of the first --policy",
    )
    parser.add_argument(
        "--video-steps",
        type=cli.non_negative_int,
        default=None,
        help="cut the video after this many steps (default: the whole episode)",
    )
    cli.add_trust_pickle(parser, "parts of the model files")
    parser.add_argument(
        "--force",
        action="store_true",
        help="evaluate models whose card names another environment or n_trailers",
    )
    cli.add_overwrite(
        parser, "replace the files of an earlier evaluation in --out and an existing --video"
    )
    return parser


def env_from_cards(specs: list[str]) -> tuple[str | None, int | None, str | None, int]:
    """The environment id, number of trailers and window of past frames on the card of
    the first model among ``specs`` that has a readable card: ``(env_id, n_trailers,
    spec, history)``, Nones and 0 without.

    A generalist's range of counts gives no n (the default 2 stands); a card that cannot
    be read is passed over here and reported when the model loads.
    """
    for spec in specs:
        if not is_model_spec(spec):
            continue
        try:
            card = model_card(spec)
        except (ValueError, FileNotFoundError, OSError):
            continue
        env_id = card.env_id
        if env_id in ENV_IDS:
            n = card.n_trailers
            return env_id, n if isinstance(n, int) else None, spec, card.env_kwargs.history or 0
    return None, None, None, 0


#: The folder the default ``--out`` lies in.
DEFAULT_OUT_ROOT = cli.OUT_ROOT / "evaluate"


def default_out(env_id: str, env_kwargs: Mapping[str, object], policies: list[str] | None) -> Path:
    """``--out``'s default: ``out/evaluate/<scene>_n<n>``, then the ``--policy`` labels
    (a model's stem, a baseline's name) and the ``--set`` settings, so that two
    evaluations of other policies, scenes or physics do not meet in one folder
    (:func:`agents.commands.options.folder_name`)."""
    labels = [policy_label(spec) for spec in policies or []]
    settings = [
        f"{key}={value if isinstance(value, str) else json.dumps(value, separators=(',', ':'))}"
        for key, value in env_kwargs.items()
        if key != "n_trailers"
    ]
    scene = f"{scene_of(env_id)}_n{env_kwargs['n_trailers']}"
    return DEFAULT_OUT_ROOT / cli.folder_name(scene, *labels, *settings)


def _check_out(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Exit 2 unless ``--out`` can take this evaluation's files (an earlier one's only
    with ``--overwrite``)."""
    cli.check_out_folder(parser, args.out, files_in=OUT_FILES)
    written = OUT_FILES[:2] if args.no_plots else OUT_FILES
    present = [name for name in written if (args.out / name).exists()]
    if present and not args.overwrite:
        parser.error(
            f"argument --out: {args.out} holds {', '.join(present)} of an earlier evaluation; "
            "pass --overwrite to replace them"
        )


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.out is not None:
        _check_out(parser, args)
    cli.check_seeds(parser, args.seed, args.episodes)
    if args.video is not None:
        from agents.evaluation.plots import VIDEO_SUFFIXES, missing_video_modules

        if args.video.suffix.lower() not in VIDEO_SUFFIXES:
            parser.error(f"argument --video: must end in .mp4 or .gif, got {args.video.name!r}")
        missing = missing_video_modules(args.video)
        if missing:
            parser.error(
                f"argument --video: needs {', '.join(missing)}: "
                "pip install 'trailer-env[rendering]'"
            )
        cli.check_out_file(parser, args.video, "--video")
        if args.video.exists() and not args.overwrite:
            parser.error(f"argument --video: {args.video} exists; pass --overwrite to replace it")
    card_env, card_n, card_of, card_history = env_from_cards(args.policy or [])
    from_card = []
    if args.env is None and card_env is not None:
        args.env = card_env
        from_card.append(card_env)
    if args.n_trailers is None and card_n is not None:
        args.n_trailers = card_n
        from_card.append(f"n = {card_n}")
    if card_history and not any(item.startswith("history=") for item in args.set):
        args.set = [*args.set, f"history={card_history}"]  # the model's memory
        from_card.append(f"history = {card_history}")
    if from_card:
        print(f"evaluate: {', '.join(from_card)} from the card of {card_of}", file=sys.stderr)
    args.env = args.env or HEADLINE_ENV_ID
    args.n_trailers = 2 if args.n_trailers is None else args.n_trailers
    env_id = check_env_id(args.env)
    env_kwargs = cli.env_kwargs_from(parser, args)
    if args.out is None:
        args.out = default_out(env_id, env_kwargs, args.policy)
        _check_out(parser, args)
    specs = args.policy or [
        *default_baselines(env_id),
        *(
            str(path)
            for path in committed_models(
                env_id, args.n_trailers, randomize=env_kwargs.get("randomize")
            )
        ),
    ]
    limit_torch_threads()
    started = time.perf_counter()
    try:
        evaluations = evaluate_policies(
            specs,
            env_id,
            env_kwargs,
            args.episodes,
            args.seed,
            trust_pickle=args.trust_pickle,
            force=args.force,
        )
    except (ValueError, FileNotFoundError) as error:
        parser.error(f"argument --policy: {error}")
    args.out.mkdir(parents=True, exist_ok=True)
    document = results_document(evaluations, env_id, env_kwargs, args.episodes, args.seed)
    files.write_json(args.out / "results.json", document.to_json())
    table = markdown_table(evaluations, curve_metric(env_id))
    files.atomic_write_text(
        args.out / "results.md",
        f"{env_id}, n = {args.n_trailers}: {plural(args.episodes, 'episode')}, seeds "
        f"{args.seed}..{args.seed + args.episodes - 1}\n\n{table}\n{table_legend([env_id])}\n",
    )
    print(table)
    print(table_legend([env_id]))
    elapsed = time.perf_counter() - started
    print(f"evaluated {plural(len(specs), 'policy', 'policies')} in {elapsed:.1f} s")
    if not args.no_plots:
        for path in write_pictures(evaluations, env_id, env_kwargs, args.out, args.seed):
            print(f"wrote {path}")
    if args.video is not None:
        from agents.evaluation import plots

        first = evaluations[0]
        assert first.policy is not None  # evaluate_policies keeps every policy
        frames = plots.episode_frames(env_id, first.policy, args.seed, env_kwargs, args.video_steps)
        fps = 1.0 / env_settings(env_kwargs).dt
        plots.write_video(frames, args.video, fps)
        print(f"wrote {args.video} ({len(frames)} frames of {first.label}, seed {args.seed})")
    print(f"wrote {args.out / 'results.json'} and {args.out / 'results.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
