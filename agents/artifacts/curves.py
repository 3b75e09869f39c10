"""Learning curves (evaluations.csv): their columns and reading them back."""

from __future__ import annotations

import csv
from pathlib import Path

#: Columns of evaluations.csv.
CURVE_COLUMNS = (
    "timesteps",
    "wall_s",
    "mean_return",
    "jackknife_rate",
    "safe_rate",
    "band_time_fraction",
    "min_margin_mean",
    "success_rate",
)


def read_curve(path: Path) -> list[dict[str, float]]:
    """Rows of an evaluations.csv as dicts of floats (empty if the file is absent)."""
    if not path.is_file():
        return []
    with path.open(newline="") as handle:
        return [{key: float(value) for key, value in row.items()} for row in csv.DictReader(handle)]


def write_curve(path: Path, rows: list[dict[str, float]]) -> None:
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=[*CURVE_COLUMNS, "iteration", "loss"])
        writer.writeheader()
        writer.writerows(rows)
