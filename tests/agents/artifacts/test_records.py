"""The typed-document base: every annotation read, refused with the field named, written back."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Literal

import pytest

from agents.artifacts.records import SCHEMA_KEY, DocumentError, JSONPart, JSONRecord
from trailer_env.objective import Objective


@dataclasses.dataclass(frozen=True)
class Start(JSONPart):
    seed: int
    status: Literal["feasible", "open"]
    fraction: float | None = None


@dataclasses.dataclass(frozen=True)
class Document(JSONRecord):
    DOCUMENT = "test document"
    SCHEMA_VERSION = 2

    name: str
    trailers: int | tuple[int, int]
    starts: tuple[Start, ...] = ()
    extra: Mapping[str, object] = dataclasses.field(default_factory=dict)
    objective: Objective = Objective.GOAL
    flag: bool = False

    def __post_init__(self) -> None:
        if not self.name:
            raise DocumentError("'name' must not be empty")


GOOD = {
    "name": "a",
    "trailers": [1, 3],
    "starts": [{"seed": 4, "status": "open", "fraction": 1}],
    "extra": {"anything": [1, {"x": None}]},
    "objective": "survival",
}


def test_reads_every_annotation() -> None:
    document = Document.from_json(GOOD, "good.json")
    assert document.trailers == (1, 3)
    assert document.starts == (Start(seed=4, status="open", fraction=1.0),)
    assert isinstance(document.starts[0].fraction, float)
    assert document.extra == {"anything": [1, {"x": None}]}
    assert document.objective is Objective.SURVIVAL
    assert document.flag is False


def test_round_trip_adds_the_schema_version_only() -> None:
    written = Document.from_json(GOOD).to_json()
    assert written[SCHEMA_KEY] == 2
    assert written["starts"] == [{"seed": 4, "status": "open", "fraction": 1.0}]
    assert SCHEMA_KEY not in written["starts"][0]  # type: ignore[index]
    assert Document.from_json(written) == Document.from_json(GOOD)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"name": None}, "test document x.json: 'name' must be str, got null"),
        ({"trailers": True}, "'trailers' must be int or a list of 2, got bool True"),
        ({"trailers": [1, 2, 3]}, "'trailers' must be int or a list of 2, got a list"),
        ({"starts": [{"seed": 1, "status": "done"}]}, "starts\\[0\\]: 'status' must be one of"),
        ({"starts": [{"seed": 1.5, "status": "open"}]}, "'seed' must be int, got float"),
        ({"starts": [{"status": "open"}]}, "starts\\[0\\]: missing field 'seed'"),
        ({"objective": "win"}, "'objective' must be one of 'survival', 'goal'"),
        ({"flag": 1}, "'flag' must be bool, got int 1"),
        ({"colour": "red"}, "unknown field 'colour'"),
        ({SCHEMA_KEY: 3}, "schema_version 3 is newer than this trailer-env reads \\(2\\)"),
        ({SCHEMA_KEY: "1"}, "schema_version must be a positive integer"),
        ({"name": ""}, "'name' must not be empty"),
    ],
)
def test_refuses_naming_the_field(change: dict[str, object], message: str) -> None:
    with pytest.raises(DocumentError, match=message):
        Document.from_json({**GOOD, **change}, "x.json")


def test_refuses_a_missing_field_and_a_non_object() -> None:
    with pytest.raises(DocumentError, match="missing field 'trailers'"):
        Document.from_json({"name": "a"})
    with pytest.raises(DocumentError, match="must be a JSON object, got a list"):
        Document.from_json([1, 2])
    assert issubclass(DocumentError, ValueError)


def test_a_document_without_a_version_is_version_one() -> None:
    assert Document.from_json({"name": "a", "trailers": 2}).trailers == 2
