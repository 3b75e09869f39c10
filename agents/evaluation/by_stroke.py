"""Where policies lose: the headline rate against how much of the rail each start needs.

Usage::

    python -m agents.evaluation.by_stroke --env trailer_env/Reverse-v1 --n-trailers 3 \\
        --policy ppo_reverse_v1_n3 dagger_reverse_v1_n3 lqr --edges 0.5,0.6,0.7 \\
        [--out FOLDER] [--overwrite]

The starts are the committed certificate's (the test seeds of a Reverse scene: the goal
scenes' certificates are not screened), each with its screen stroke:
the smallest share of the rail's stroke that recovers it under the linearisation
(:mod:`agents.oracles.screen`), a measure of how hard the start is that no policy
influences. Every ``--policy`` plays the same starts (one batched rollout each); the
table counts, per band of stroke (``--edges``, shares of ``s_max``), the starts, those
the certificate proves feasible, and those each policy saves (the scene's headline
outcome: safe on Reverse, success on the goal scenes). Below it, the starts that every
policy loses. Printed, and with ``--out`` written as ``by_stroke.md`` and
``by_stroke.json``, atomically (existing files are replaced only with ``--overwrite``).
"""

from __future__ import annotations

import argparse
import itertools
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TypedDict, cast

import numpy as np

from agents.artifacts import files
from agents.artifacts.certificates import FEASIBLE, committed_certificate
from agents.envs import ENV_IDS, headline_metric
from agents.evaluation.metrics import rollout
from agents.policies.registry import load_policy, policy_label
from trailer_env.json_types import JSONObject

OUTPUTS = ("by_stroke.md", "by_stroke.json")


class StrokeBand(TypedDict):
    """One band of screen stroke ``[low, high)`` (None: open) and its counts of starts."""

    low: float | None
    high: float | None
    starts: int
    feasible: int
    saved: dict[str, int]


def certificate_strokes(certificate: JSONObject) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(seeds, screen stroke fractions, feasible)`` of a certificate's starts.

    Raises:
        ValueError: If the seeds are not consecutive or a start lacks its screen stroke.
    """
    starts = certificate["starts"]
    seeds = np.array([int(start["seed"]) for start in starts])
    if seeds.size == 0 or np.any(np.diff(seeds) != 1):
        raise ValueError("the certificate's seeds are not one consecutive range")
    unscreened = [
        int(start["seed"])
        for start in starts
        if not files.is_number(start.get("screen_stroke_fraction"))
    ]
    if unscreened:
        raise ValueError(
            f"{len(unscreened)} starts of the certificate (from seed {unscreened[0]}) have no "
            "screen stroke: only the Reverse scenes' certificates are screened"
        )
    strokes = np.array([float(start["screen_stroke_fraction"]) for start in starts])
    feasible = np.array([start["status"] == FEASIBLE for start in starts])
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
            {
                "low": None if np.isinf(low) else float(low),
                "high": None if np.isinf(high) else float(high),
                "starts": int(inside.sum()),
                "feasible": int((inside & feasible).sum()),
                "saved": {label: int((inside & won).sum()) for label, won in saved.items()},
            }
        )
    return rows


def _band_name(row: StrokeBand) -> str:
    low, high = row["low"], row["high"]
    if low is None:
        return f"< {high:g}"
    if high is None:
        return f">= {low:g}"
    return f"{low:g} - {high:g}"


def markdown(
    rows: Sequence[StrokeBand],
    labels: Sequence[str],
    lost_by_all: Sequence[int],
    strokes_of_lost: Sequence[float],
) -> str:
    """The table (a column per band of stroke, a row per count: the starts, the feasible
    ones, each policy's saved ones) and the line naming the starts every policy loses."""
    lines = [
        "| screen stroke (share of s_max) | " + " | ".join(_band_name(row) for row in rows) + " |",
        "|---" * (1 + len(rows)) + "|",
        "| starts | " + " | ".join(str(row["starts"]) for row in rows) + " |",
        "| certified feasible | " + " | ".join(str(row["feasible"]) for row in rows) + " |",
    ]
    for label in labels:
        counts = [row["saved"][label] for row in rows]
        lines.append(f"| saved by {label} | " + " | ".join(str(count) for count in counts) + " |")
    lost = ", ".join(
        f"{seed} ({stroke:.2f})" for seed, stroke in zip(lost_by_all, strokes_of_lost, strict=True)
    )
    lines += ["", f"Lost by every policy (seed, screen stroke): {lost or 'none'}."]
    return "\n".join(lines) + "\n"


def by_stroke(
    env_id: str, n_trailers: int, policies: Sequence[str], edges: Sequence[float]
) -> JSONObject:
    """Play ``policies`` on the committed certificate's starts and band them by stroke.

    Raises:
        ValueError: If the scene and n have no committed certificate, or a policy cannot
            be loaded for them.
    """
    certificate = committed_certificate(env_id, n_trailers)
    if certificate is None:
        raise ValueError(f"{env_id} with n = {n_trailers} has no committed certificate")
    seeds, strokes, feasible = certificate_strokes(certificate)
    kwargs: JSONObject = {"n_trailers": n_trailers}
    loaded = {
        policy_label(spec): load_policy(spec, env_id, kwargs, seed=int(seeds[0]))
        for spec in policies
    }
    outcome = "safe" if headline_metric(env_id) == "safe_rate" else "success"
    saved: dict[str, np.ndarray] = {}
    for label, policy in loaded.items():
        results = rollout(policy, env_id, seeds.size, int(seeds[0]), kwargs)
        saved[label] = np.asarray(getattr(results, outcome), dtype=bool)
    lost = ~np.logical_or.reduce(list(saved.values()))
    return {
        "env_id": env_id,
        "n_trailers": n_trailers,
        "seeds": [int(seeds[0]), int(seeds[-1])],
        "outcome": outcome,
        "edges": [float(edge) for edge in edges],
        "policies": list(saved),
        "bands": cast(list[JSONObject], band_rows(strokes, feasible, saved, edges)),
        "lost_by_all": [int(seed) for seed in seeds[lost]],
        "lost_by_all_strokes": [float(stroke) for stroke in strokes[lost]],
    }


def _edges(text: str) -> list[float]:
    try:
        edges = [float(part) for part in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected numbers separated by commas; got {text!r}"
        ) from None
    if not all(np.isfinite(edges)) or any(b <= a for a, b in itertools.pairwise(edges)):
        raise argparse.ArgumentTypeError(f"the edges must be finite and increasing; got {text!r}")
    return edges


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m agents.evaluation.by_stroke",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--env",
        default="trailer_env/Reverse-v1",
        choices=ENV_IDS,
        metavar="ENV_ID",
        help=f"one of {', '.join(ENV_IDS)} (default trailer_env/Reverse-v1)",
    )
    parser.add_argument("--n-trailers", type=int, required=True)
    parser.add_argument(
        "--policy", nargs="+", required=True, help="policy specs, as agents.evaluate's"
    )
    parser.add_argument(
        "--edges", type=_edges, default=[0.5, 0.6, 0.7], help="band edges (default 0.5,0.6,0.7)"
    )
    parser.add_argument(
        "--out", type=Path, default=None, help="also write the table and figures here"
    )
    parser.add_argument(
        "--overwrite", action="store_true", help="replace by_stroke.md and .json in --out"
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.out is not None and not args.overwrite:
        existing = [name for name in OUTPUTS if (args.out / name).exists()]
        if existing:
            parser.error(f"{args.out} already holds {', '.join(existing)}: pass --overwrite")
    try:
        document = by_stroke(args.env, args.n_trailers, args.policy, args.edges)
    except ValueError as error:
        parser.error(str(error))
    text = markdown(
        cast(list[StrokeBand], document["bands"]),
        document["policies"],
        document["lost_by_all"],
        document["lost_by_all_strokes"],
    )
    sys.stdout.write(text)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        files.atomic_write_text(args.out / OUTPUTS[0], text)
        files.write_json(args.out / OUTPUTS[1], document)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
