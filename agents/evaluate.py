"""Evaluate policies (baselines by name, saved models by path) over K seeded episodes.

Usage::

    python -m agents.evaluate --env trailer_env/Reverse-v0 --n-trailers 2 \\
        --policy zero random lqr ppo_reverse_n2 --episodes 100 --out out/eval

A policy is a baseline name, the stem of a shipped model (``ppo_reverse_n2`` is the
installed package's ``agents/models/ppo_reverse_n2.zip``, from any folder), a model
zip's path or an RLlib checkpoint folder (``runs/<run>/checkpoint``). Model files are
loaded without unpickling anything unless ``--trust-pickle``
(:mod:`agents.model_files`), and a model whose card names another environment id or
number of trailers is refused unless ``--force``. ``--video PATH.mp4|.gif`` also
writes every frame of one episode (seed ``--seed``) of the first policy.

Without ``--policy`` it evaluates the scene's baselines and every committed model
(``agents/models/*.zip``) trained for that environment and number of trailers.
All episodes of one policy run in one native batch; episode ``i`` is seeded
``seed + i`` (default seed 1000), so the same command gives the same JSON.

Writes to ``--out``: ``results.json`` (every metric, per policy), ``results.md``
(a Markdown table, also printed), and unless ``--no-plots``: ``margins.png``
(singular-margin histograms), ``frames.png`` (a rendered episode per policy) and
``curves.png`` (learning curves of the models that have them).
"""

from __future__ import annotations

import argparse
import json
import re
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from agents import cli
from agents.baselines import BASELINES, Policy
from agents.envs import check_env_id, env_settings, headline_metric, scene_baselines
from agents.metrics import EpisodeResults, rollout, summarize
from agents.model_files import curve_path
from agents.policies import (
    MODELS_DIR,
    is_model_spec,
    limit_torch_threads,
    load_policy,
    policy_label,
    read_card,
    resolve_model,
)

#: First seed of the test episodes (training validation uses 50000 and up).
TEST_SEED = 1000
#: The models of every training seed of the committed models (see :func:`seed_models`).
SEEDS_DIR = MODELS_DIR / "seeds"


@dataclass
class Evaluation:
    """One policy's evaluation: its label, spec, model card (if any), results and policy."""

    label: str
    spec: str
    card: dict[str, Any]
    results: EpisodeResults
    policy: Policy | None = None
    #: Per training seed (a committed model's siblings in ``agents/models/seeds/``): its
    #: card's seed and the same episodes' summary.
    seed_summaries: list[tuple[int | None, dict[str, Any]]] | None = None

    @property
    def summary(self) -> dict[str, Any]:
        """Aggregate metrics (:func:`agents.metrics.summarize`)."""
        return summarize(self.results)

    def seed_spread(self, metric: str = "safe_rate") -> tuple[float, float, float, float] | None:
        """(mean, sd, min, max) of ``metric`` over the training seeds, or None without them."""
        if not self.seed_summaries:
            return None
        values = np.array([summary[metric] for _, summary in self.seed_summaries])
        return float(values.mean()), float(values.std()), float(values.min()), float(values.max())


def curve_metric(env_id: str) -> str:
    """The headline rate of a scene, as its core declares it (``headline_metric``)."""
    return headline_metric(env_id)


def default_baselines(env_id: str) -> list[str]:
    """The baselines that fit ``env_id``, as its core declares them (``baselines``)."""
    return list(scene_baselines(env_id))


def committed_models(env_id: str, n_trailers: int, directory: Path = MODELS_DIR) -> list[Path]:
    """Models under ``directory`` whose card names ``env_id`` and ``n_trailers``."""
    found = []
    for path in sorted(directory.glob("*.zip")):
        card = read_card(path)
        if (
            card.get("env_id") == env_id
            and card.get("env_kwargs", {}).get("n_trailers") == n_trailers
        ):
            found.append(path)
    return found


def seed_models(spec: str, directory: Path = SEEDS_DIR) -> list[Path]:
    """The models of every training seed of a committed model: ``<seeds>/<stem>_s<k>.zip``.

    A committed model is the best of its configuration's training seeds; the others (and
    a copy of it) are kept under ``agents/models/seeds/`` so that tables can report the
    spread over seeds. Only a model in the folder above ``directory`` has siblings (a
    model of the same name from anywhere else is not the committed one). Empty for
    baselines and for models without siblings.
    """
    if not is_model_spec(spec):
        return []
    path = Path(resolve_model(spec))
    if path.is_dir() or path.resolve().parent != directory.resolve().parent:
        return []
    pattern = re.compile(re.escape(path.stem) + r"_s\d+")
    return sorted(
        candidate
        for candidate in directory.glob(f"{path.stem}_s*.zip")
        if pattern.fullmatch(candidate.stem)
    )


def model_card(spec: str) -> dict[str, Any]:
    """The card of a model spec (SB3 zip or RLlib checkpoint); empty for a baseline."""
    if not is_model_spec(spec):
        return {}
    path = Path(resolve_model(spec))
    if path.is_dir():
        from agents.rllib_backend import read_rllib_card

        return read_rllib_card(path)
    return read_card(path)


def load_policies(
    specs: Sequence[str],
    env_id: str,
    env_kwargs: dict[str, Any],
    seed: int = TEST_SEED,
    *,
    trust_pickle: bool = False,
    force: bool = False,
) -> list[tuple[str, Policy]]:
    """Load every spec first (so a bad one fails before any episode runs): (spec, policy).

    Shipped models' stems are resolved to their paths (:func:`agents.policies.resolve_model`).
    """
    return [
        (
            resolve_model(spec),
            load_policy(
                spec, env_id, env_kwargs, seed=seed, trust_pickle=trust_pickle, force=force
            ),
        )
        for spec in specs
    ]


def evaluate_policies(
    specs: Sequence[str],
    env_id: str,
    env_kwargs: dict[str, Any],
    episodes: int,
    seed: int = TEST_SEED,
    *,
    trust_pickle: bool = False,
    force: bool = False,
    with_seeds: bool = True,
) -> list[Evaluation]:
    """Evaluate each policy spec on the same ``episodes`` seeded episodes.

    Args:
        trust_pickle, force: As for :func:`agents.policies.load_policy`.
        with_seeds: Also evaluate every training seed of a committed model
            (:func:`seed_models`) on the same episodes.
    """
    evaluations = []
    loaded = load_policies(specs, env_id, env_kwargs, seed, trust_pickle=trust_pickle, force=force)
    for spec, policy in loaded:
        results = rollout(policy, env_id, episodes, seed, env_kwargs)
        siblings = seed_models(spec) if with_seeds else []
        seed_summaries = None
        if siblings:
            seed_summaries = []
            for sibling, sibling_policy in load_policies(
                [str(path) for path in siblings], env_id, env_kwargs, seed,
                trust_pickle=trust_pickle, force=force,
            ):  # fmt: skip
                sibling_results = rollout(sibling_policy, env_id, episodes, seed, env_kwargs)
                seed_summaries.append((model_card(sibling).get("seed"), summarize(sibling_results)))
        evaluations.append(
            Evaluation(policy_label(spec), spec, model_card(spec), results, policy, seed_summaries)
        )
    return evaluations


def oracle_note(label: str, episode_steps: int = 400) -> str:
    """What the table says in the training column of a baseline ("-" unless an oracle)."""
    if label != "mpc":
        return "-"
    from agents.planner import PlannerConfig

    per_episode = PlannerConfig().steps_per_decision * episode_steps
    return f"oracle: exact model and state, {per_episode / 1000:.0f}k simulated steps per episode"


def training_note(card: dict[str, Any], label: str = "") -> str:
    """ "PPO, seed 0, 2.0M steps, 95 s" from a model card ("-" for baselines)."""
    if not card:
        return oracle_note(label)

    def steps_text(steps: float) -> str:
        return f"{steps / 1e6:.3g}M" if steps >= 100_000 else f"{steps / 1e3:.3g}k"

    steps = card.get("timesteps", card.get("budget", 0))
    selected = card.get("selected_at_timesteps")
    chosen = f" (kept {steps_text(selected)})" if selected not in (None, steps) else ""
    wall = card.get("wall_time_s")
    wall_text = f", {wall:.0f} s" if isinstance(wall, (int, float)) else ""
    algo = str(card.get("algo", "?")).upper()
    if card.get("recipe") == "dagger":
        iteration = card.get("selected_at_iteration")
        kept = f" (kept iteration {iteration})" if iteration is not None else ""
        return (
            f"{algo} policy by DAgger from mpc, seed {card.get('seed')}, "
            f"{steps_text(steps)} labels{kept}{wall_text}"
        )
    return f"{algo}, seed {card.get('seed')}, {steps_text(steps)} steps{chosen}{wall_text}"


def seeds_note(evaluation: Evaluation, metric: str = "safe_rate") -> str:
    """ "96 ± 2% (94-98, 3 seeds)": ``metric`` over the training seeds, or "-"."""
    spread = evaluation.seed_spread(metric)
    if spread is None:
        return "-"
    mean, sd, low, high = (100 * value for value in spread)
    count = len(evaluation.seed_summaries or [])
    return f"{mean:.0f} ± {sd:.0f}% ({low:.0f}-{high:.0f}, {count} seeds)"


def markdown_table(evaluations: Sequence[Evaluation], metric: str = "safe_rate") -> str:
    """The comparison table in Markdown (rates in %, margins in [0, 1]).

    The last column gives ``metric`` (the scene's headline rate) over a committed
    model's training seeds.

    "stopped reversing" counts the failures that are not folds: on Reverse-v0 the
    episodes ended because the cart's speed reached u >= 0 (other scenes have none).
    """
    header = (
        "| policy | training | return (mean ± sd) | safe episodes [95% CI] | jackknife "
        "| time in band | min margin (mean / worst) | success | stopped reversing "
        f"| {metric.removesuffix('_rate')} over training seeds |\n"
        "|---|---|---|---|---|---|---|---|---|---|\n"
    )
    lines = []
    for evaluation in evaluations:
        s = evaluation.summary
        stopped = s["failure_rate"] - s["jackknife_rate"]
        low, high = s["safe_rate_ci"]
        lines.append(
            f"| {evaluation.label} | {training_note(evaluation.card, evaluation.label)} "
            f"| {s['mean_return']:.1f} ± {s['std_return']:.1f} "
            f"| {100 * s['safe_rate']:.0f}% [{100 * low:.0f}, {100 * high:.0f}] "
            f"| {100 * s['jackknife_rate']:.0f}% | {100 * s['band_time_fraction']:.1f}% "
            f"| {s['min_margin_mean']:.2f} / {s['min_margin_worst']:.2f} "
            f"| {100 * s['success_rate']:.0f}% | {100 * stopped:.0f}% "
            f"| {seeds_note(evaluation, metric)} |"
        )
    return header + "\n".join(lines) + "\n"


def results_document(
    evaluations: Sequence[Evaluation],
    env_id: str,
    env_kwargs: dict[str, Any],
    episodes: int,
    seed: int,
) -> dict[str, Any]:
    """Everything an evaluation found, as JSON-ready data (no timings: deterministic)."""
    return {
        "env_id": env_id,
        "env_kwargs": env_kwargs,
        "episodes": episodes,
        "seeds": [seed, seed + episodes - 1],
        "safe": "never in the singular band, never folded, never stopped reversing",
        "policies": [
            {
                "name": evaluation.label,
                "kind": "model" if is_model_spec(evaluation.spec) else "baseline",
                "training": {
                    key: evaluation.card[key]
                    for key in ("algo", "seed", "budget", "timesteps", "wall_time_s", "n_envs")
                    if key in evaluation.card
                },
                **evaluation.summary,
                **(
                    {}
                    if evaluation.seed_summaries is None
                    else {
                        "training_seeds": [
                            {"seed": seed, **summary} for seed, summary in evaluation.seed_summaries
                        ]
                    }
                ),
            }
            for evaluation in evaluations
        ],
    }


def learning_curve(evaluation: Evaluation) -> Path | None:
    """The learning curve (``evaluations.csv`` exported as ``<model>.csv``) of a model, if any."""
    if not is_model_spec(evaluation.spec):
        return None
    curve = curve_path(Path(evaluation.spec))
    return curve if curve.is_file() else None


def baseline_levels(evaluations: Sequence[Evaluation], metric: str) -> dict[str, float]:
    """The baselines' ``metric``, drawn as levels over the learning curves.

    The random baseline is left out: it marks no level a trained agent is measured
    against (zero and the controllers do).
    """
    return {
        e.label: e.summary[metric]
        for e in evaluations
        if not is_model_spec(e.spec) and e.label != "random"
    }


def write_pictures(
    evaluations: Sequence[Evaluation],
    env_id: str,
    env_kwargs: dict[str, Any],
    out: Path,
    seed: int,
    prefix: str = "",
) -> list[Path]:
    """Margin histograms, rendered frames and (if any) learning curves under ``out``."""
    from agents import plots

    settings = env_settings(env_kwargs)
    n = settings.n_trailers
    title = f"{env_id}, n = {n}, {evaluations[0].results.returns.size} episodes"
    written = [
        plots.plot_margin_histograms(
            {e.label: e.results for e in evaluations},
            settings.singular_band,
            out / f"{prefix}margins.png",
            title,
        )
    ]
    rows = {}
    for evaluation in evaluations:
        if evaluation.label == "random":
            continue
        policy = evaluation.policy or load_policy(evaluation.spec, env_id, env_kwargs, seed=seed)
        rows[evaluation.label] = plots.render_frames(env_id, policy, seed, env_kwargs)
    if rows:
        written.append(plots.plot_frames(rows, out / f"{prefix}frames.png"))
    curves = {e.label: curve for e in evaluations if (curve := learning_curve(e)) is not None}
    if curves:
        metric = curve_metric(env_id)
        title = f"{env_id}, n = {n}: validation episodes during training"
        written.append(
            plots.plot_learning_curves(
                curves,
                out / f"{prefix}curves.png",
                baseline_levels(evaluations, metric),
                title,
                metric,
            )
        )
    return written


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog="python -m agents.evaluate",
        description="Evaluate baselines and saved agents over seeded episodes.",
    )
    cli.add_env(parser, default="trailer_env/Reverse-v0")
    cli.add_n_trailers(parser)
    parser.add_argument(
        "--policy",
        nargs="+",
        default=None,
        metavar="POLICY",
        help=f"baselines ({', '.join(BASELINES)}), shipped models by stem "
        "(e.g. ppo_reverse_n2), model paths (.zip) and/or RLlib checkpoint folders; "
        "default: the scene's baselines and its committed models",
    )
    cli.add_episodes(parser, 100, "episodes (default 100)")
    cli.add_seed(parser, TEST_SEED, f"episode i is seeded seed + i (default {TEST_SEED})")
    parser.add_argument(
        "--out", type=Path, default=Path("out/eval"), help="output folder (default out/eval)"
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
    cli.add_overwrite(parser, "replace an existing --video file")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    cli.check_out_folder(parser, args.out)
    if args.video is not None:
        from agents.plots import VIDEO_SUFFIXES

        if args.video.suffix.lower() not in VIDEO_SUFFIXES:
            parser.error(f"argument --video: must end in .mp4 or .gif, got {args.video.name!r}")
        if args.video.exists() and not args.overwrite:
            parser.error(f"argument --video: {args.video} exists; pass --overwrite to replace it")
    env_id = check_env_id(args.env)
    env_kwargs = {"n_trailers": args.n_trailers}
    try:
        env_settings(env_kwargs)
    except (TypeError, ValueError) as error:
        parser.error(f"argument --n-trailers: {error}")
    specs = args.policy or [
        *default_baselines(env_id),
        *(str(path) for path in committed_models(env_id, args.n_trailers)),
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
    (args.out / "results.json").write_text(json.dumps(document, indent=2, sort_keys=True) + "\n")
    table = markdown_table(evaluations, curve_metric(env_id))
    (args.out / "results.md").write_text(
        f"{env_id}, n = {args.n_trailers}: {args.episodes} episodes, seeds "
        f"{args.seed}..{args.seed + args.episodes - 1}\n\n{table}"
    )
    print(table, end="")
    print(f"evaluated {len(specs)} policies in {time.perf_counter() - started:.1f} s")
    if not args.no_plots:
        for path in write_pictures(evaluations, env_id, env_kwargs, args.out, args.seed):
            print(f"wrote {path}")
    if args.video is not None:
        from agents import plots

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
