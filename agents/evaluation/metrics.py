"""Seeded batched rollouts and the safety metrics: the benchmark protocol's own
(:mod:`trailer_env.benchmark`), so that the project's tables and any other stack's
scores come from one implementation; :func:`summary_of` reads its summary as a
:class:`~agents.artifacts.results.Summary` record."""

from __future__ import annotations

from agents.artifacts.results import Summary
from trailer_env.benchmark import EpisodeResults, rollout, summarize, wilson_interval


def summary_of(results: EpisodeResults) -> Summary:
    """The aggregate metrics of ``results`` (:func:`summarize`) by attribute."""
    return Summary.from_json(summarize(results), "of the episodes")


__all__ = ["EpisodeResults", "Summary", "rollout", "summarize", "summary_of", "wilson_interval"]
