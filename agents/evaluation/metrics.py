"""Seeded batched rollouts and the safety metrics: the benchmark protocol's own
(:mod:`trailer_env.benchmark`), so that the project's tables and any other stack's
scores come from one implementation."""

from __future__ import annotations

from trailer_env.benchmark import EpisodeResults, rollout, summarize, wilson_interval

__all__ = ["EpisodeResults", "rollout", "summarize", "wilson_interval"]
