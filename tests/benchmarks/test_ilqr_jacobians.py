"""The iLQR Jacobians benchmark: its committed table is the one its CSV gives."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from benchmarks.ilqr_jacobians import MODES, SCENES, main, table

RESULTS = Path(__file__).resolve().parents[2] / "benchmarks" / "results"


def test_the_committed_table_is_written_from_the_committed_rows() -> None:
    with open(RESULTS / "ilqr_jacobians.csv", newline="") as file:
        rows = list(csv.DictReader(line for line in file if not line.startswith("#")))
    assert [(row["env_id"], int(row["n_trailers"]), row["jacobians"]) for row in rows] == [
        (env_id, n, mode) for env_id, n in SCENES for mode in MODES
    ]
    for row in rows:
        starts = int(row["starts"])
        assert starts == 100
        assert int(row["success"]) + int(row["open"]) == starts
        assert int(row["first_pass_success"]) <= int(row["success"])
        assert float(row["first_pass_wall_time_s"]) <= float(row["wall_time_s"])
    text = (RESULTS / "ilqr_jacobians.md").read_text()
    body = table(rows, "").strip().splitlines()
    assert text.strip().splitlines()[: len(body)] == body


@pytest.mark.slow
def test_quick_run_writes_both_modes(tmp_path: Path) -> None:
    main(["--quick", "--results", str(tmp_path)])
    with open(tmp_path / "ilqr_jacobians.csv", newline="") as file:
        rows = list(csv.DictReader(line for line in file if not line.startswith("#")))
    assert [row["jacobians"] for row in rows] == list(MODES)
    assert all(int(row["starts"]) == 10 for row in rows)
    assert (tmp_path / "ilqr_jacobians.md").read_text().count("| Coast-v0 | 1 |") == 2
