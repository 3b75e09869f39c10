"""agents.mismatch: ceilings and safe rates against the size of the parameter mismatch."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents.commands import mismatch
from agents.evaluation.mismatch import MISMATCHED, CountSweep, markdown, preset
from agents.evaluation.mismatch import env_kwargs as sweep_kwargs


def test_the_sizes_name_the_presets() -> None:
    assert preset(0) is None
    assert preset(30) == "mismatch30"
    assert sweep_kwargs("lqr", 2, "mismatch30") == {"n_trailers": 2, "randomize": "mismatch30"}
    assert sweep_kwargs("dagger_reverse_v1_memory", 1, None) == {"n_trailers": 1, "history": 16}


def test_the_most_costly_parameter_is_the_largest_drop_of_the_blind_policies() -> None:
    sweep = CountSweep(2, ["lqr", "lqr-adaptive", "m"])
    sweep.ceiling = {0: 1.0, 20: 0.98}
    sweep.open = {0: 0, 20: 2}
    sweep.rates = {
        0: {"lqr": (0.9, 0.9), "lqr-adaptive": (0.9, 0.9), "m": (1.0, 0.99)},
        20: {"lqr": (0.7, 0.72), "lqr-adaptive": (0.88, 0.9), "m": (0.95, 0.93)},
    }
    sweep.alone = {name: {"lqr": 0.9, "lqr-adaptive": 0.9, "m": 1.0} for name in MISMATCHED}
    sweep.alone["a"] = {"lqr": 0.8, "lqr-adaptive": 0.2, "m": 0.97}  # 0.13 blind drop
    sweep.alone["mu"] = {"lqr": 0.85, "lqr-adaptive": 0.9, "m": 0.9}  # 0.15: the most
    assert sweep.most_costly() == "mu"
    table = markdown([sweep], 100, 1000, 7000)
    assert "| ceiling | 100 | 98 (2 open) |" in table
    assert "| lqr | 90 / 90 | 70 / 72 |" in table
    assert "| m | 100 / 99 | 95 / 93 |" in table
    assert "**n = 2**: mu" in table
    assert "| lqr-adaptive | 90 | 90 | 20 | 90 | 90 |" in table


@pytest.mark.slow
def test_the_command_writes_every_output(tmp_path: Path) -> None:
    out = tmp_path / "mismatch"
    argv = ["--n", "1", "--sizes", "0", "20", "--policy", "lqr", "--episodes", "3"]
    assert mismatch.main([*argv, "--out", str(out)]) == 0
    assert sorted(path.name for path in out.iterdir()) == [
        "mismatch.json",
        "mismatch.md",
        "mismatch_n1.png",
    ]
    document = json.loads((out / "mismatch.json").read_text())
    by_n = document["by_n"]["1"]
    assert by_n["ceiling"] == {"0": 1.0, "20": 1.0}  # the committed certificates' first 3
    assert set(by_n["safe_rate"]) == {"0", "20"}
    assert set(by_n["alone"]) == set(MISMATCHED)
    assert by_n["most_costly"] in MISMATCHED


def test_a_size_without_preset_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exit_info:
        mismatch.main(["--sizes", "0", "25", "--out", str(tmp_path / "m")])
    assert exit_info.value.code == 2
    assert "a size is 0 or one of [10, 20, 30, 40], got '25'" in capsys.readouterr().err
    assert not (tmp_path / "m").exists()


def test_existing_outputs_are_kept_without_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "mismatch.md").write_text("kept")
    with pytest.raises(SystemExit) as exit_info:
        mismatch.main(["--n", "1", "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    assert "pass --overwrite" in capsys.readouterr().err
    assert (tmp_path / "mismatch.md").read_text() == "kept"


def test_redraw_writes_the_committed_table_again_from_its_json(tmp_path: Path) -> None:
    committed = Path(__file__).resolve().parents[3] / "docs" / "generated" / "mismatch"
    (tmp_path / "mismatch.json").write_text((committed / "mismatch.json").read_text())
    assert mismatch.main(["--redraw", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "mismatch.md").read_text() == (committed / "mismatch.md").read_text()
    assert sorted(path.name for path in tmp_path.glob("*.png")) == [
        "mismatch_n1.png",
        "mismatch_n2.png",
        "mismatch_n3.png",
    ]


def test_redraw_refuses_a_damaged_document(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "mismatch.json").write_text(
        json.dumps({"episodes": 3, "seed": 1000, "fresh_seed": 7000, "by_n": {"1": {}}})
    )
    with pytest.raises(SystemExit) as exit_info:
        mismatch.main(["--redraw", "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    assert "n = 1 is not a sweep's figures" in capsys.readouterr().err
    assert sorted(path.name for path in tmp_path.iterdir()) == ["mismatch.json"]
