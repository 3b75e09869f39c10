"""The headline outcome banded by the screen stroke each start needs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from agents.artifacts.certificates import committed_certificate
from agents.commands.by_stroke import main
from agents.evaluation.by_stroke import ByStroke, band_rows, certificate_strokes, markdown


def test_bands_count_every_start_once_and_the_saved_ones_inside_them() -> None:
    strokes = np.array([0.1, 0.49, 0.5, 0.65, 0.7, 0.95])
    feasible = np.array([True, True, True, True, True, False])
    saved = {"a": np.array([True, True, False, True, False, False])}
    rows = band_rows(strokes, feasible, saved, [0.5, 0.7])
    assert [(r.low, r.high, r.starts, r.feasible) for r in rows] == [
        (None, 0.5, 2, 2),
        (0.5, 0.7, 2, 2),
        (0.7, None, 2, 1),
    ]
    assert [r.saved["a"] for r in rows] == [2, 1, 0]
    text = markdown(rows, ["a"], [1004], [0.7])
    assert "| screen stroke (share of s_max) | < 0.5 | 0.5 - 0.7 | >= 0.7 |" in text
    assert "| certified feasible | 2 | 2 | 1 |" in text
    assert "| saved by a | 2 | 1 | 0 |" in text
    assert text.rstrip().endswith("1004 (0.70).")


def test_the_committed_certificate_gives_one_stroke_per_test_start() -> None:
    certificate = committed_certificate("trailer_env/Reverse-v1", 1)
    assert certificate is not None
    seeds, strokes, feasible = certificate_strokes(certificate)
    assert seeds[0] == 1000 and seeds.size == 100
    assert np.all((strokes > 0.0) & (strokes < 1.0))  # sized so the hardest needs ~80 %
    assert feasible.sum() == round(100 * certificate.ceiling)
    moved = certificate.starts[0].replace(seed=5)
    broken = certificate.replace(starts=(moved, *certificate.starts[1:]))
    with pytest.raises(ValueError, match="consecutive"):
        certificate_strokes(broken)


@pytest.mark.slow
def test_the_command_writes_the_table_and_refuses_to_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "bands"
    args = ["--n-trailers", "1", "--policy", "zero", "--edges", "0.3,0.6", "--out", str(out)]
    assert main(args) == 0
    table = ByStroke.from_json(json.loads((out / "by_stroke.json").read_text()))
    assert sum(band.starts for band in table.bands) == 100
    assert table.policies == ("zero",) and table.outcome == "safe"
    zero_saved = sum(band.saved["zero"] for band in table.bands)
    assert len(table.lost_by_all) == 100 - zero_saved
    assert table.markdown() == (out / "by_stroke.md").read_text()
    assert (out / "by_stroke.md").read_text() == capsys.readouterr().out
    before = (out / "by_stroke.md").read_text()
    with pytest.raises(SystemExit):
        main(args)
    assert "pass --overwrite" in capsys.readouterr().err
    assert (out / "by_stroke.md").read_text() == before
    with pytest.raises(SystemExit):
        main(["--n-trailers", "1", "--policy", "zero", "--edges", "0.6,0.3"])
    assert "increasing" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--n-trailers", "9", "--policy", "zero"])
    assert "no committed certificate" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--env", "trailer_env/Dock-v0", "--n-trailers", "1", "--policy", "zero"])
    assert "no screen stroke" in capsys.readouterr().err
