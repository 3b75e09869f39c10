"""agents.estimation: the estimating baseline's error against time and rates."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents.commands import estimation
from agents.evaluation.estimation import OUTPUTS, POLICIES


@pytest.mark.slow
def test_the_error_falls_and_every_output_is_written(tmp_path: Path) -> None:
    out = tmp_path / "estimation"
    assert estimation.main(["--n", "1", "--episodes", "2", "--out", str(out)]) == 0
    assert sorted(path.name for path in out.iterdir()) == sorted(OUTPUTS)
    document = json.loads((out / "estimation.json").read_text())
    by_n = document["by_n"]["1"]
    assert by_n["parameters"] == ["M", "J0", "a", "l", "mu"]
    errors = by_n["relative_error"]
    assert max(errors[0]) > 0.01  # the nominal start is off by the draw
    assert max(errors[-1]) < 1e-3  # the fit recovers every parameter to 0.1 %
    assert set(by_n["rates"]) == set(POLICIES)
    assert "| 1 | " in (out / "estimation.md").read_text()


def test_existing_outputs_are_kept_without_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "estimation.md").write_text("kept")
    with pytest.raises(SystemExit) as exit_info:
        estimation.main(["--n", "1", "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    assert "pass --overwrite" in capsys.readouterr().err
    assert (tmp_path / "estimation.md").read_text() == "kept"
    assert sorted(path.name for path in tmp_path.iterdir()) == ["estimation.md"]


def test_a_bad_episode_count_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        estimation.main(["--episodes", "0", "--out", str(tmp_path / "e")])
    assert exit_info.value.code == 2
    assert "--episodes" in capsys.readouterr().err
    assert not (tmp_path / "e").exists()
