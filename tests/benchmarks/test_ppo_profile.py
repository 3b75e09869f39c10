"""``python -m benchmarks.ppo_profile --quick``: the parts add up to the whole iteration."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from benchmarks import ppo_profile


def test_the_parts_of_a_ppo_iteration_add_up(tmp_path: Path) -> None:
    assert ppo_profile.main(["--quick", "--results", str(tmp_path)]) == 0
    with (tmp_path / "ppo_profile.csv").open() as handle:
        (row,) = list(csv.DictReader(handle))
    parts = [float(row[key]) for key in ppo_profile.CATEGORIES]
    assert all(part > 0 for part in parts)
    assert sum(parts) == pytest.approx(float(row["learn"]), rel=1e-9)
    assert float(row["steps"]) == 16384  # one rollout of the committed n_steps x n_envs
