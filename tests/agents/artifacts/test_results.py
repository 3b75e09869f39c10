"""The results document and the metrics summary: written as the file has always held them
(the summary's fields beside each policy's name), read back by attribute, bad ones refused
with the field named."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents.artifacts.cards import ModelCard
from agents.artifacts.records import SCHEMA_KEY, DocumentError
from agents.artifacts.results import ResultsDocument, Summary, TrainingFacts, read_results
from agents.evaluation.metrics import EpisodeResults, summarize, summary_of
from agents.evaluation.results import Evaluation, results_document

V1 = "trailer_env/Reverse-v1"


def _results() -> EpisodeResults:
    """Four episodes: three safe, one folded."""
    return EpisodeResults(
        seeds=np.arange(4),
        returns=np.array([100.0, 200.0, 300.0, 400.0]),
        lengths=np.array([400, 400, 120, 400]),
        jackknifed=np.array([False, False, True, False]),
        success=np.array([True, True, False, True]),
        failed=np.array([False, False, True, False]),
        band_steps=np.zeros(4, dtype=np.int64),
        min_margin=np.array([1.0, 1.0, 0.2, 0.9]),
        actuator_work=np.zeros(4),
        margins=np.ones(4),
    )


def _document() -> ResultsDocument:
    card = ModelCard(algo="ppo", seed=2, timesteps=1000, wall_time_s=12.5)
    summary = summary_of(_results())
    seeds: list[tuple[int | None, Summary]] = [(0, summary), (1, summary.replace(safe_rate=0.5))]
    evaluations = [
        Evaluation("lqr", "lqr", ModelCard(), _results()),
        Evaluation("m", "m.zip", card, _results(), None, seeds),
    ]
    return results_document(evaluations, V1, {"n_trailers": 2}, 4, 1000)


def test_the_summary_reads_summarize_by_attribute() -> None:
    summary = summary_of(_results())
    assert summary.to_json() == summarize(_results())
    assert (summary.episodes, summary.safe_rate, summary.jackknife_rate) == (4, 0.75, 0.25)
    assert summary.rate("success_rate") == 0.75 and summary.stop_rate == 0.0
    with pytest.raises(ValueError, match="no rate 'mean_return'"):
        summary.rate("mean_return")


def test_the_results_document_is_written_flat_and_read_back(tmp_path: Path) -> None:
    document = _document()
    written = document.to_json()
    assert written[SCHEMA_KEY] == 1 and written["seeds"] == [1000, 1003]
    lqr, model = written["policies"]
    assert lqr["name"] == "lqr" and lqr["kind"] == "baseline" and lqr["training"] == {}
    assert lqr["safe_rate"] == 0.75 and "summary" not in lqr and "training_seeds" not in lqr
    assert model["kind"] == "model"
    assert model["training"] == {"algo": "ppo", "seed": 2, "timesteps": 1000, "wall_time_s": 12.5}
    assert [seed["safe_rate"] for seed in model["training_seeds"]] == [0.75, 0.5]
    assert "fresh" not in written and "ceiling" not in written
    path = tmp_path / "results.json"
    path.write_text(json.dumps(written))
    assert read_results(path) == (document,)
    both = document.replace(fresh=document, ceiling="ceiling: 96 %")
    path.write_text(json.dumps([written, both.to_json()]))
    assert read_results(path) == (document, both)
    again = read_results(path)[1]
    assert again.fresh == document and again.by_kind("model")[0].training == TrainingFacts(
        algo="ppo", seed=2, timesteps=1000, wall_time_s=12.5
    )


@pytest.mark.parametrize(
    ("change", "named"),
    [
        (lambda d: d.pop("episodes"), "missing field 'episodes'"),
        (lambda d: d.update(seeds=[1000, 1001]), "'seeds' 1000..1001"),
        (lambda d: d["policies"][0].pop("safe_rate"), "missing field 'safe_rate'"),
        (lambda d: d["policies"][0].update(kind="oracle"), "'kind' must be one of"),
        (lambda d: d["policies"][1]["training"].update(colour=1), "unknown field 'colour'"),
        (lambda d: d.update(extra=1), "unknown field 'extra'"),
    ],
)
def test_a_bad_results_document_is_refused_naming_the_field(
    tmp_path: Path, change: Callable[[dict[str, Any]], object], named: str
) -> None:
    written = json.loads(json.dumps(_document().to_json()))
    change(written)
    path = tmp_path / "results.json"
    path.write_text(json.dumps(written))
    with pytest.raises(DocumentError, match=named):
        read_results(path)
