"""Where policies lose: the headline rate against how much of the rail each start needs.

The starts are the committed certificate's (the test seeds of a Reverse scene: the goal
scenes' certificates are not screened), each with its screen stroke: the smallest share
of the rail's stroke that recovers it under the linearisation
(:mod:`agents.oracles.screen`), a measure of how hard the start is that no policy
influences. Every policy plays the same starts (one batched rollout each); the table
counts, per band of stroke (shares of ``s_max``), the starts, those the certificate
proves feasible, and those each policy saves (the scene's headline outcome: safe on a
survival scene, success on a goal scene). Below it, the starts that every policy loses.
The program is :mod:`agents.commands.by_stroke` (``python -m agents.by_stroke``).
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Mapping, Sequence
from typing import ClassVar, Literal

import numpy as np

from agents.artifacts.certificates import Certificate, committed_certificate
from agents.artifacts.records import JSONPart, JSONRecord
from agents.evaluation.metrics import rollout
from agents.policies.registry import load_policy, policy_label
from trailer_env.objective import Objective
from trailer_env.registry import core_class_of

#: The files the program writes.
OUTPUTS = ("by_stroke.md", "by_stroke.json")


@dataclasses.dataclass(frozen=True, kw_only=True)
class StrokeBand(JSONPart):
    """One band of screen stroke ``[low, high)`` (None: open) and its counts of starts."""

    low: float | None
    high: float | None
    starts: int
    feasible: int
    #: Policy label -> the starts of the band it saves.
    saved: Mapping[str, int]

    @property
    def name(self) -> str:
        """The band as a column title: ``< 0.5``, ``0.5 - 0.6``, ``>= 0.7``."""
        if self.low is None:
            return f"< {self.high:g}"
        if self.high is None:
            return f">= {self.low:g}"
        return f"{self.low:g} - {self.high:g}"


@dataclasses.dataclass(frozen=True, kw_only=True)
class ByStroke(JSONRecord):
    """by_stroke.json: every policy's saved starts, band by band, and the starts all lose."""

    DOCUMENT: ClassVar[str] = "by-stroke table"

    env_id: str
    n_trailers: int
    seeds: tuple[int, int]
    outcome: Literal["safe", "success"]
    edges: tuple[float, ...]
    policies: tuple[str, ...]
    bands: tuple[StrokeBand, ...]
    lost_by_all: tuple[int, ...]
    lost_by_all_strokes: tuple[float, ...]

    def markdown(self) -> str:
        """The table (a column per band of stroke, a row per count: the starts, the
        feasible ones, each policy's saved ones) and the line naming the starts every
        policy loses."""
        return markdown(self.bands, self.policies, self.lost_by_all, self.lost_by_all_strokes)


def certificate_strokes(certificate: Certificate) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(seeds, screen stroke fractions, feasible)`` of a certificate's starts.

    Raises:
        ValueError: If the seeds are not consecutive or a start lacks its screen stroke.
    """
    starts = certificate.starts
    seeds = np.array([start.seed for start in starts])
    if seeds.size == 0 or np.any(np.diff(seeds) != 1):
        raise ValueError("the certificate's seeds are not one consecutive range")
    unscreened = [start.seed for start in starts if start.screen_stroke_fraction is None]
    if unscreened:
        raise ValueError(
            f"{len(unscreened)} starts of the certificate (from seed {unscreened[0]}) have no "
            "screen stroke: only the Reverse scenes' certificates are screened"
        )
    strokes = np.array([start.screen_stroke_fraction for start in starts], dtype=np.float64)
    feasible = np.array([start.feasible for start in starts])
    return seeds, strokes, feasible


def band_rows(
    strokes: np.ndarray,
    feasible: np.ndarray,
    saved: Mapping[str, np.ndarray],
    edges: Sequence[float],
) -> list[StrokeBand]:
    """One row per band ``[edges[k-1], edges[k])`` (open at both ends): its starts, the
    feasible ones and each policy's saved ones, as counts."""
    bounds = [-np.inf, *edges, np.inf]
    rows: list[StrokeBand] = []
    for low, high in itertools.pairwise(bounds):
        inside = (strokes >= low) & (strokes < high)
        rows.append(
            StrokeBand(
                low=None if np.isinf(low) else float(low),
                high=None if np.isinf(high) else float(high),
                starts=int(inside.sum()),
                feasible=int((inside & feasible).sum()),
                saved={label: int((inside & won).sum()) for label, won in saved.items()},
            )
        )
    return rows


def markdown(
    rows: Sequence[StrokeBand],
    labels: Sequence[str],
    lost_by_all: Sequence[int],
    strokes_of_lost: Sequence[float],
) -> str:
    """The table (a column per band of stroke, a row per count: the starts, the feasible
    ones, each policy's saved ones) and the line naming the starts every policy loses."""
    lines = [
        "| screen stroke (share of s_max) | " + " | ".join(row.name for row in rows) + " |",
        "|---" * (1 + len(rows)) + "|",
        "| starts | " + " | ".join(str(row.starts) for row in rows) + " |",
        "| certified feasible | " + " | ".join(str(row.feasible) for row in rows) + " |",
    ]
    for label in labels:
        counts = [row.saved[label] for row in rows]
        lines.append(f"| saved by {label} | " + " | ".join(str(count) for count in counts) + " |")
    lost = ", ".join(
        f"{seed} ({stroke:.2f})" for seed, stroke in zip(lost_by_all, strokes_of_lost, strict=True)
    )
    lines += ["", f"Lost by every policy (seed, screen stroke): {lost or 'none'}."]
    return "\n".join(lines) + "\n"


def by_stroke(
    env_id: str, n_trailers: int, policies: Sequence[str], edges: Sequence[float]
) -> ByStroke:
    """Play ``policies`` on the committed certificate's starts and band them by stroke.

    Raises:
        ValueError: If the scene and n have no committed certificate, or a policy cannot
            be loaded for them.
    """
    certificate = committed_certificate(env_id, n_trailers)
    if certificate is None:
        raise ValueError(f"{env_id} with n = {n_trailers} has no committed certificate")
    seeds, strokes, feasible = certificate_strokes(certificate)
    kwargs: dict[str, object] = {"n_trailers": n_trailers}
    loaded = {
        policy_label(spec): load_policy(spec, env_id, kwargs, seed=int(seeds[0]))
        for spec in policies
    }
    survival = core_class_of(env_id).objective is Objective.SURVIVAL
    outcome: Literal["safe", "success"] = "safe" if survival else "success"
    saved: dict[str, np.ndarray] = {}
    for label, policy in loaded.items():
        results = rollout(policy, env_id, seeds.size, int(seeds[0]), kwargs)
        saved[label] = np.asarray(getattr(results, outcome), dtype=bool)
    lost = ~np.logical_or.reduce(list(saved.values()))
    return ByStroke(
        env_id=env_id,
        n_trailers=n_trailers,
        seeds=(int(seeds[0]), int(seeds[-1])),
        outcome=outcome,
        edges=tuple(float(edge) for edge in edges),
        policies=tuple(saved),
        bands=tuple(band_rows(strokes, feasible, saved, edges)),
        lost_by_all=tuple(int(seed) for seed in seeds[lost]),
        lost_by_all_strokes=tuple(float(stroke) for stroke in strokes[lost]),
    )


__all__ = ["OUTPUTS", "ByStroke", "StrokeBand", "band_rows", "by_stroke", "certificate_strokes"]
