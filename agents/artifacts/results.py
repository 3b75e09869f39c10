"""The results document (``results.json`` of ``agents.evaluate`` and ``agents.report``) and
the metrics summary it is made of, as typed records.

:class:`Summary` is :func:`trailer_env.benchmark.summarize`'s dict read by attribute. A
:class:`ResultsDocument` holds the episodes every policy ran on and one
:class:`PolicyResult` per policy: its name, kind, the training facts of its model card
(:class:`TrainingFacts`), its summary (the summary's fields beside the others, as the file
has always held them) and, for a committed model, each training seed's summary
(:class:`SeedResult`). The report's documents also hold the same policies on fresh starts
(:attr:`ResultsDocument.fresh`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import ClassVar, Literal

from agents.algorithms.options import FineTune
from agents.artifacts import files
from agents.artifacts.cards import HostSpeed, ModelCard
from agents.artifacts.records import (
    DocumentError,
    JSONPart,
    JSONRecord,
    RecordT,
    SparsePart,
    SparseRecord,
)

#: The rates of a summary a scene may report first (its core's ``headline_metric``).
RATES = ("safe_rate", "success_rate", "jackknife_rate", "failure_rate")

#: What "safe" means in the results (written into each document).
SAFE_TEXT = "never in the singular band, never folded, never stopped reversing"


@dataclasses.dataclass(frozen=True)
class Summary(JSONPart):
    """The aggregate metrics of a batch of episodes (:func:`trailer_env.benchmark.summarize`:
    its docstring defines each)."""

    DOCUMENT: ClassVar[str] = "metrics summary"

    episodes: int
    mean_return: float
    std_return: float
    mean_length: float
    jackknife_rate: float
    failure_rate: float
    safe_rate: float
    safe_rate_ci: tuple[float, float]
    band_time_fraction: float
    min_margin_mean: float
    min_margin_worst: float
    success_rate: float
    mean_abs_actuator_work: float

    def rate(self, metric: str) -> float:
        """The rate ``metric`` (one of :data:`RATES`, e.g. a scene's headline metric).

        Raises:
            ValueError: For another name.
        """
        if metric not in RATES:
            raise ValueError(f"no rate {metric!r} in a summary ({', '.join(RATES)})")
        value = getattr(self, metric)
        assert isinstance(value, float)
        return value

    @property
    def stop_rate(self) -> float:
        """The failures that are not folds (the scene's ``failure_words``)."""
        return self.failure_rate - self.jackknife_rate

    def fields(self) -> dict[str, object]:
        """The summary's fields (JSON-ready), to write beside others."""
        return self.to_json()


def _field_names(cls: type[JSONRecord]) -> tuple[str, ...]:
    return tuple(field.name for field in dataclasses.fields(cls))


@dataclasses.dataclass(frozen=True)
class TrainingFacts(SparsePart):
    """What a policy's model card says of its training (absent for a baseline)."""

    algo: str | None = None
    recipe: str | None = None
    init_from: str | None = None
    seed: int | None = None
    budget: int | None = None
    timesteps: int | None = None
    wall_time_s: float | None = None
    n_envs: int | None = None
    #: The machine's speed when the run started (None: not recorded on its card).
    host: HostSpeed | None = None

    @classmethod
    def of(cls, card: ModelCard) -> TrainingFacts:
        """The facts ``card`` holds (``init_from``: its fine-tuning option's start)."""
        fine_tune = card.option(FineTune)
        facts = {name: getattr(card, name) for name in _field_names(cls) if name != "init_from"}
        return cls(**facts, init_from=None if fine_tune is None else fine_tune.init_from)


def _gather_summary(data: object) -> object:
    """An entry as written (the summary's fields beside the others) with the summary's
    fields gathered under ``summary``, as the record reads it."""
    if not isinstance(data, dict):
        return data
    names = set(_field_names(Summary))
    summary = {key: value for key, value in data.items() if key in names}
    rest = {key: value for key, value in data.items() if key not in names}
    return {**rest, "summary": summary}


@dataclasses.dataclass(frozen=True)
class SeedResult(JSONPart):
    """One training seed's model on the same episodes: its card's seed and summary."""

    seed: int | None
    summary: Summary

    @classmethod
    def _read(cls: type[RecordT], data: object, label: str, *, versioned: bool) -> RecordT:
        return super()._read(_gather_summary(data), label, versioned=versioned)

    def to_json(self) -> dict[str, object]:
        """The entry as written: ``seed`` beside the summary's fields."""
        return {"seed": self.seed, **self.summary.fields()}


@dataclasses.dataclass(frozen=True)
class PolicyResult(JSONPart):
    """One policy's results: what it is, how it was trained, its summary."""

    name: str
    kind: Literal["model", "callable", "ensemble", "baseline"]
    summary: Summary
    training: TrainingFacts = TrainingFacts()
    #: A committed model's training seeds on the same episodes (None: not evaluated).
    training_seeds: tuple[SeedResult, ...] | None = None

    @classmethod
    def _read(cls: type[RecordT], data: object, label: str, *, versioned: bool) -> RecordT:
        return super()._read(_gather_summary(data), label, versioned=versioned)

    def to_json(self) -> dict[str, object]:
        """The entry as written: the summary's fields beside ``name``, ``kind`` ..."""
        document: dict[str, object] = {
            "name": self.name,
            "kind": self.kind,
            "training": self.training.to_json(),
            **self.summary.fields(),
        }
        if self.training_seeds is not None:
            document["training_seeds"] = [seed.to_json() for seed in self.training_seeds]
        return document


@dataclasses.dataclass(frozen=True)
class ResultsDocument(SparseRecord):
    """Everything one evaluation found (no timings: deterministic)."""

    DOCUMENT: ClassVar[str] = "results document"
    ALWAYS: ClassVar[tuple[str, ...]] = ("safe", "policies")

    env_id: str
    env_kwargs: Mapping[str, object]
    episodes: int
    #: The first and last episode seed.
    seeds: tuple[int, int]
    safe: str = SAFE_TEXT
    policies: tuple[PolicyResult, ...] = ()
    #: The same policies on fresh starts (the report's documents).
    fresh: ResultsDocument | None = None
    #: The scenario's ceiling line (:func:`agents.evaluation.ceiling.ceiling_note`), where
    #: the program writes it.
    ceiling: str | None = None

    def __post_init__(self) -> None:
        if self.episodes < 1:
            raise DocumentError(f"'episodes' must be >= 1, got {self.episodes}")
        first, last = self.seeds
        if last - first + 1 != self.episodes:
            raise DocumentError(
                f"'seeds' {first}..{last} are not the {self.episodes} episodes' seeds"
            )

    def by_kind(self, kind: str) -> tuple[PolicyResult, ...]:
        """The policies of ``kind`` ("model", "callable", "ensemble" or "baseline")."""
        return tuple(policy for policy in self.policies if policy.kind == kind)

    @property
    def n_trailers(self) -> object:
        """The ``n_trailers`` the policies ran with (as written; None: the default)."""
        return self.env_kwargs.get(N_TRAILERS)


#: The keyword of the number of trailers in ``env_kwargs``.
N_TRAILERS = "n_trailers"


def read_results(path: Path) -> tuple[ResultsDocument, ...]:
    """The results documents of a ``results.json``: ``agents.evaluate``'s one document, or
    ``agents.report``'s list of them (one per scenario).

    Raises:
        ValueError: If the file is too large or deep, not JSON, or a document does not
            fit :class:`ResultsDocument` (naming the field).
    """
    data = files.read_json(path, "results")
    documents = data if isinstance(data, list) else [data]
    return tuple(
        ResultsDocument.from_json(
            document, f"{path}[{index}]" if isinstance(data, list) else str(path)
        )
        for index, document in enumerate(documents)
    )


__all__ = [
    "RATES",
    "PolicyResult",
    "ResultsDocument",
    "SeedResult",
    "Summary",
    "TrainingFacts",
    "read_results",
]
