"""The leaderboard's panels: each policy's kind comes from its baseline record."""

from __future__ import annotations

import dataclasses

import pytest

from agents.artifacts.results import ResultsDocument, Summary
from agents.evaluation.leaderboard import panel_of
from agents.policies.baselines import BASELINES


def _entry(name: str, kind: str, rate: float) -> dict:
    fields = {field.name: 0.0 for field in dataclasses.fields(Summary)}
    summary = {**fields, "episodes": 100, "safe_rate_ci": [0.0, 1.0], "safe_rate": rate}
    return {"name": name, "kind": kind, **summary, "success_rate": rate}


def _document(n_trailers: object, policies: list[dict]) -> ResultsDocument:
    raw = {
        "env_id": "trailer_env/Reverse-v1",
        "env_kwargs": {"n_trailers": n_trailers},
        "episodes": 100,
        "seeds": [1000, 1099],
        "policies": policies,
    }
    return ResultsDocument.from_json(raw, "test")


def test_kinds_come_from_the_baseline_records() -> None:
    document = _document(
        3,
        [
            _entry("lqr", "baseline", 0.91),
            _entry("mpc", "baseline", 0.99),
            _entry("mpc-replay", "baseline", 1.0),
            _entry("zero", "baseline", 0.0),
            _entry("dagger_reverse_v1_n3", "model", 0.97),
            _entry("my_module:act", "callable", 0.5),
        ],
    )
    panel = panel_of(document)
    kinds = {standing.name: standing.kind for standing in panel.standings}
    assert kinds == {
        "lqr": "lqr",
        "mpc": "oracle",
        "mpc-replay": "oracle",
        "zero": "other",
        "dagger_reverse_v1_n3": "learned",
        "my_module:act": "learned",
    }
    assert panel.lqr == 0.91 and panel.ceiling == pytest.approx(1.0)  # n = 3 certified
    assert (panel.standings[0].low, panel.standings[0].high) == pytest.approx(
        (0.838, 0.952), abs=1e-3
    )
    oracles = {name for name, record in BASELINES.items() if record.oracle_note is not None}
    assert oracles == {"mpc", "ilqr", "mpc-replay"}
    every = panel_of(_document(2, [_entry(name, "baseline", 0.5) for name in BASELINES]))
    assert {s.name for s in every.standings if s.kind == "oracle"} == oracles


def test_a_range_of_counts_has_no_panel() -> None:
    with pytest.raises(ValueError, match="one count of trailers, got"):
        panel_of(_document([1, 3], [_entry("lqr", "baseline", 0.5)]))
