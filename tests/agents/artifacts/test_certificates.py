"""The certificate record: every committed certificate reads and writes back unchanged."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest

from agents.artifacts.certificates import (
    CERTIFICATES_DIR,
    FEASIBLE,
    OPEN,
    Certificate,
    DocumentError,
    markdown,
    read_certificate,
    write_certificate,
)
from agents.artifacts.records import SCHEMA_KEY
from tests.agents.helpers import fake_certified

COMMITTED = sorted(CERTIFICATES_DIR.glob("*.json"))


def test_every_committed_certificate_is_found() -> None:
    assert len(COMMITTED) == 27


@pytest.mark.parametrize("path", COMMITTED, ids=lambda path: path.stem)
def test_a_committed_certificate_reads_and_writes_back_the_same_document(path: Path) -> None:
    document = json.loads(path.read_text())
    certificate = Certificate.from_json(document, str(path))
    written = certificate.to_json()
    assert written.pop(SCHEMA_KEY) == Certificate.SCHEMA_VERSION
    # Certificates written before documents carried a version read as version 1.
    assert document.pop(SCHEMA_KEY, Certificate.SCHEMA_VERSION) == Certificate.SCHEMA_VERSION
    assert written == document
    assert Certificate.from_json(certificate.to_json()) == certificate
    assert certificate.episodes == len(certificate.starts) == 100
    assert certificate.feasible + certificate.not_recoverable + certificate.open == 100
    assert certificate.ceiling == certificate.feasible / 100
    assert certificate.goal == (certificate.screen.is_applied is False)


def test_the_statuses_and_sources_read_as_attributes() -> None:
    certificate = read_certificate(CERTIFICATES_DIR / "dock_n2.json")
    assert (certificate.env_id, certificate.n_trailers) == ("trailer_env/Dock-v0", 2)
    assert certificate.goal and certificate.planner.label == "ilqr"
    assert sum(certificate.source_counts().values()) == certificate.feasible == 100
    assert next(iter(certificate.source_counts())) == "ilqr"  # the planner's first
    reverse = read_certificate(CERTIFICATES_DIR / "reverse_n1.json")
    assert reverse.planner.label == "mpc" and not reverse.goal
    assert all(reverse.source_of(start) == "mpc" for start in reverse.starts)


def _edit(path: str, value: object) -> Callable[[dict[str, object]], None]:
    def edit(document: dict[str, object]) -> None:
        *parents, name = path.split(".")
        target: object = document
        for parent in parents:
            target = target[int(parent)] if isinstance(target, list) else target[parent]  # type: ignore[index]
        target[name] = value  # type: ignore[index]

    return edit


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (_edit("ceiling", 0.5), "ceiling must be the feasible fraction"),
        (_edit("feasible", "2"), "'feasible' must be int"),
        (_edit("open", 1), "open must be the number of 'open' starts"),
        (_edit("episodes", 3), "episodes must be the number of starts"),
        (_edit("starts.0.status", "great"), "'status' must be one of 'feasible'"),
        (_edit("starts.0.seed", "x"), "'seed' must be int"),
        (_edit("starts.1.seed", 1), "every seed must appear once"),
        (_edit("starts.0.screen_stroke_fraction", "inf"), "'screen_stroke_fraction' must be"),
        (_edit("starts.0.screen_stroke_fraction", float("nan")), "non-finite number NaN"),
        (_edit("starts.0.planner_length", -1), "planner_length must be an integer >= 0"),
        (_edit("starts.0.colour", "red"), "unknown field 'colour'"),
        (_edit("env_kwargs.n_trailers", -1), "n_trailers must be an integer >= 0"),
        (_edit("planner.wall_time_s", None), "'wall_time_s' must be float"),
        (_edit("sources", {"mpc": 1}), "sources must count the feasible starts"),
        (_edit(SCHEMA_KEY, 99), "newer than this trailer-env reads"),
    ],
)
def test_a_malformed_certificate_is_refused_naming_the_field(
    tmp_path: Path, edit: Callable[[dict[str, object]], None], message: str
) -> None:
    document = fake_certified([1, 2]).certificate.to_json()
    edit(document)
    path = tmp_path / "c.json"
    path.write_text(json.dumps(document))
    with pytest.raises(ValueError, match=message) as refused:
        read_certificate(path)
    assert str(path) in str(refused.value) and "\n" not in str(refused.value)


def test_a_parsed_non_finite_stroke_is_refused() -> None:
    document = fake_certified([1]).certificate.to_json()
    document["starts"][0]["screen_stroke_fraction"] = float("inf")  # type: ignore[index]
    with pytest.raises(DocumentError, match="seed 1: screen_stroke_fraction must be a finite"):
        Certificate.from_json(document, "parsed")


def test_a_source_only_on_a_feasible_start() -> None:
    open_start = fake_certified([1], status=OPEN).certificate.starts[0]
    with pytest.raises(DocumentError, match="source only on a feasible start"):
        open_start.replace(source="lqr")


def test_recounting_new_starts_keeps_the_counts_consistent() -> None:
    certificate = fake_certified([1, 2, 3], status=OPEN).certificate
    solved = certificate.starts[0].replace(status=FEASIBLE, source="lqr", replay_safe=True)
    recounted = certificate.with_starts((solved, *certificate.starts[1:]))
    assert (recounted.feasible, recounted.open, recounted.episodes) == (1, 2, 3)
    assert recounted.ceiling == pytest.approx(1 / 3)
    assert recounted.sources is None  # kept only where the certificate keeps them
    counted = recounted.replace(sources=recounted.source_counts())
    assert counted.sources == {"lqr": 1}


def test_writing_sets_each_feasible_start_s_record_file(tmp_path: Path) -> None:
    written = write_certificate(fake_certified([4, 5]), tmp_path / "cert", overwrite=False)
    assert [start.actions_file for start in written.starts] == [
        "actions/seed_4.npy",
        "actions/seed_5.npy",
    ]
    assert read_certificate(tmp_path / "cert" / "certificate.json") == written
    assert (tmp_path / "cert" / "certificate.md").read_text() == markdown(written)
