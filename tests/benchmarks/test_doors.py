"""``python -m benchmarks.doors --quick``: one row per door and N, ratios from the rates."""

from __future__ import annotations

import csv
import math
import sys
from pathlib import Path

import pytest

from benchmarks import doors

COLUMNS = [
    "door",
    "label",
    "num_envs",
    "measured",
    "steps_per_second",
    "ns_per_env_step",
    "ratio_native",
    "ratio_bare",
    "note",
]


def test_every_door_has_a_row_and_the_ratios_come_from_the_rates(tmp_path: Path) -> None:
    assert doors.main(["--quick", "--results", str(tmp_path), "--images", str(tmp_path)]) == 0
    with (tmp_path / "doors.csv").open() as handle:
        reader = csv.DictReader(handle)
        assert reader.fieldnames == COLUMNS
        rows = list(reader)
    keys = [(row["door"], int(row["num_envs"])) for row in rows]
    assert keys == [(door.key, size) for door in doors.DOORS for size in doors.QUICK_SIZES]
    rate = {key: float(row["steps_per_second"]) for key, row in zip(keys, rows, strict=True)}
    for (door, size), row in zip(keys, rows, strict=True):
        if row["measured"] == "True":
            assert rate[door, size] > 0
            assert float(row["ns_per_env_step"]) == pytest.approx(1e9 / rate[door, size])
            assert float(row["ratio_native"]) == pytest.approx(
                rate[door, size] / rate["native", size], rel=1e-12
            )
            assert float(row["ratio_bare"]) == pytest.approx(
                rate[door, size] / rate["bare", size], rel=1e-12
            )
        else:
            assert row["note"], (door, size)  # every door not measured says why
            assert math.isnan(rate[door, size])
    measured = {key for key, row in zip(keys, rows, strict=True) if row["measured"] == "True"}
    assert {("native", 1), ("native", 16), ("sb3", 16), ("bare", 16), ("single", 1)} <= measured
    assert ("single", 16) not in measured
    table = (tmp_path / "doors.md").read_text()
    assert "N = 16" in table and "not measured" in table
    assert (tmp_path / "bench_doors.png").stat().st_size > 0


def test_a_missing_dependency_skips_its_door_with_a_note(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "torchrl", None)  # import torchrl raises ImportError
    monkeypatch.setitem(sys.modules, "ray", None)
    cases = doors.plan(doors.SIZES)
    notes = {(case.door.key, case.num_envs): case.note for case in cases}
    for size in doors.SIZES:
        assert notes["torchrl", size] == "skipped: torchrl not installed (ModuleNotFoundError)"
        assert notes["rllib", size] == "skipped: ray not installed (ModuleNotFoundError)"
        assert notes["native", size] == ""
    assert notes["async", 16] == ""
    assert notes["async", 256].startswith("not measured: one process per env")
    rows = doors.rows_of(cases)  # nothing built: every row reported, none measured
    assert len(rows) == len(doors.DOORS) * len(doors.SIZES)
    assert not any(row["measured"] for row in rows)
