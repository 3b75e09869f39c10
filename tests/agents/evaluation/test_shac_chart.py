"""The SHAC chart reads the committed runs whole and writes only where and when told."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from agents.commands.shac_chart import main
from agents.evaluation.shac_chart import read_shac_curve

RUNS = Path("docs/generated/shac/runs")
PNG = b"\x89PNG\r\n\x1a\n"


def test_the_committed_run_reads_as_its_file_says() -> None:
    curve = read_shac_curve(RUNS / "reverse_v1_n1_shac_s0")
    peak = int(np.argmax(curve.safe_rate))
    # Its evaluations.csv: the mean action peaks at 0.953 after 1,175 windows, where the
    # noisy actor holds 0.016 of the starts; 0.094 at 1,350, 0 at 1,375.
    assert (curve.iteration[peak], curve.safe_rate[peak]) == (1175, pytest.approx(0.953125))
    assert curve.sampled_safe_rate[peak] == pytest.approx(0.015625)
    falls = {int(i): rate for i, rate in zip(curve.iteration, curve.safe_rate, strict=True)}
    assert falls[1350] == pytest.approx(0.09375) and falls[1375] == 0.0
    assert curve.label == "reverse_v1_n1_shac_s0" and curve.iteration.size == 60


def test_the_chart_is_written_once_and_replaced_only_when_asked(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "charts" / "shac.png"
    runs = [str(RUNS / "reverse_v1_n1_shac_s0"), str(RUNS / "reverse_v1_n1_shac_bound10_s0")]
    assert main([*runs, "--out", str(out)]) == 0
    assert out.read_bytes().startswith(PNG)
    out.write_bytes(b"mine")
    with pytest.raises(SystemExit) as refused:
        main([*runs, "--out", str(out)])
    assert refused.value.code == 2 and "--overwrite" in capsys.readouterr().err
    assert out.read_bytes() == b"mine"
    assert main([*runs, "--out", str(out), "--overwrite"]) == 0
    assert out.read_bytes().startswith(PNG)


def test_a_run_without_the_columns_is_refused_before_anything_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # The ladder's SHAC run predates the noisy actor's column.
    old = tmp_path / "old"
    shutil.copytree("docs/generated/ladder/runs/reverse_v1_n1_shac_s0", old)
    out = tmp_path / "shac.png"
    with pytest.raises(SystemExit) as refused:
        main([str(RUNS / "reverse_v1_n1_shac_s0"), str(old), "--out", str(out)])
    assert refused.value.code == 2 and "sampled_safe_rate" in capsys.readouterr().err
    bad = tmp_path / "bad"
    shutil.copytree(RUNS / "reverse_v1_n1_shac_s0", bad)
    csv = bad / "evaluations.csv"
    csv.write_text(csv.read_text().replace(",0.953125,", ",1.953125,"))
    with pytest.raises(ValueError, match="safe_rate outside"):
        read_shac_curve(bad)
    with pytest.raises(SystemExit):
        main([str(RUNS / "reverse_v1_n1_shac_s0"), "--out", str(tmp_path / "shac.jpg")])
    assert not out.exists() and not (tmp_path / "shac.jpg").exists()
