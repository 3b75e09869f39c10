"""Evaluating policies on the same seeded episodes, and the results as JSON-ready data."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from agents.artifacts.cards import ModelCard
from agents.artifacts.results import (
    PolicyResult,
    ResultsDocument,
    SeedResult,
    Summary,
    TrainingFacts,
)
from agents.artifacts.shipped import resolve_model, seed_models
from agents.envs import MakeKwargs, headline_metric, scene_baselines
from agents.evaluation.metrics import EpisodeResults, rollout, summary_of
from agents.policies.baselines import Policy
from agents.policies.ensemble import is_ensemble_spec
from agents.policies.mirror import split_mirror
from agents.policies.registry import (
    is_callable_spec,
    is_model_spec,
    load_policy,
    model_card,
    policy_label,
    window_kwargs,
)
from agents.progress import Progress
from agents.seeds import TEST_SEED


@dataclass
class Evaluation:
    """One policy's evaluation: its label, spec, model card (if any), results and policy."""

    label: str
    spec: str
    #: The model's card (the empty card for a baseline).
    card: ModelCard
    results: EpisodeResults
    policy: Policy | None = None
    #: Per training seed (a committed model's siblings in ``agents/models/seeds/``): its
    #: card's seed and the same episodes' summary.
    seed_summaries: list[tuple[int | None, Summary]] | None = None

    @property
    def summary(self) -> Summary:
        """Aggregate metrics (:func:`agents.evaluation.metrics.summary_of`)."""
        return summary_of(self.results)

    def seed_spread(self, metric: str = "safe_rate") -> tuple[float, float, float, float] | None:
        """(mean, sd, min, max) of ``metric`` over the training seeds, or None without them."""
        if not self.seed_summaries:
            return None
        values = np.array([summary.rate(metric) for _, summary in self.seed_summaries])
        return float(values.mean()), float(values.std()), float(values.min()), float(values.max())


def curve_metric(env_id: str) -> str:
    """The headline rate of a scene, as its core declares it (``headline_metric``)."""
    return headline_metric(env_id)


def default_baselines(env_id: str) -> list[str]:
    """The baselines that fit ``env_id``, as its core declares them (``baselines``)."""
    return list(scene_baselines(env_id))


def load_policies(
    specs: Sequence[str],
    env_id: str,
    env_kwargs: MakeKwargs,
    seed: int = TEST_SEED,
    *,
    trust_pickle: bool = False,
    force: bool = False,
) -> list[tuple[str, Policy]]:
    """Load every spec first (so a bad one fails before any episode runs): (spec, policy).

    Shipped models' stems are resolved to their paths
    (:func:`agents.artifacts.shipped.resolve_model`); a model with a memory is loaded for
    its window (:func:`agents.policies.registry.window_kwargs`).
    """
    return [
        (
            resolve_model(spec),
            load_policy(
                spec,
                env_id,
                window_kwargs(spec, env_kwargs),
                seed=seed,
                trust_pickle=trust_pickle,
                force=force,
            ),
        )
        for spec in specs
    ]


def evaluate_policies(
    specs: Sequence[str],
    env_id: str,
    env_kwargs: MakeKwargs,
    episodes: int,
    seed: int = TEST_SEED,
    *,
    trust_pickle: bool = False,
    force: bool = False,
    with_seeds: bool = True,
    progress: bool = True,
) -> list[Evaluation]:
    """Evaluate each policy spec on the same ``episodes`` seeded episodes.

    Args:
        trust_pickle, force: As for :func:`agents.policies.registry.load_policy`.
        with_seeds: Also evaluate every training seed of a committed model
            (:func:`seed_models`) on the same episodes.
        progress: Report each policy's evaluation on standard error
            (:class:`agents.progress.Progress`).
    """
    evaluations = []
    loaded = load_policies(specs, env_id, env_kwargs, seed, trust_pickle=trust_pickle, force=force)
    siblings = {spec: seed_models(spec) if with_seeds else [] for spec, _ in loaded}
    total = len(loaded) + sum(len(paths) for paths in siblings.values())
    with Progress(total, f"evaluating on {env_id}", quiet=not progress) as bar:
        for spec, policy in loaded:
            results = rollout(policy, env_id, episodes, seed, window_kwargs(spec, env_kwargs))
            bar.advance(policy_label(spec))
            seed_summaries = None
            if siblings[spec]:
                seed_summaries = []
                for sibling, sibling_policy in load_policies(
                    [str(path) for path in siblings[spec]],
                    env_id,
                    env_kwargs,
                    seed,
                    trust_pickle=trust_pickle,
                    force=force,
                ):
                    sibling_results = rollout(
                        sibling_policy, env_id, episodes, seed, window_kwargs(sibling, env_kwargs)
                    )
                    card = model_card(sibling)
                    seed_summaries.append((card.seed, summary_of(sibling_results)))
                    bar.advance(policy_label(sibling))
            evaluations.append(
                Evaluation(
                    policy_label(spec), spec, model_card(spec), results, policy, seed_summaries
                )
            )
    return evaluations


def results_document(
    evaluations: Sequence[Evaluation],
    env_id: str,
    env_kwargs: Mapping[str, object],
    episodes: int,
    seed: int,
) -> ResultsDocument:
    """Everything an evaluation found (no timings: deterministic)."""
    return ResultsDocument(
        env_id=env_id,
        env_kwargs=dict(env_kwargs),
        episodes=episodes,
        seeds=(seed, seed + episodes - 1),
        policies=tuple(
            PolicyResult(
                name=evaluation.label,
                kind=spec_kind(evaluation.spec),
                summary=evaluation.summary,
                training=TrainingFacts.of(evaluation.card),
                training_seeds=None
                if evaluation.seed_summaries is None
                else tuple(
                    SeedResult(seed, summary) for seed, summary in evaluation.seed_summaries
                ),
            )
            for evaluation in evaluations
        ),
    )


def spec_kind(spec: str) -> Literal["model", "callable", "ensemble", "baseline"]:
    """ "model", "callable" (``module:name``), "ensemble" (``median(...)``) or
    "baseline", for the results' JSON."""
    if is_model_spec(spec):
        return "model"
    if is_ensemble_spec(split_mirror(spec)[0]):
        return "ensemble"
    return "callable" if is_callable_spec(spec) else "baseline"
