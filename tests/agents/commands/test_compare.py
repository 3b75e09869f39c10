"""``python -m agents.compare``: several evaluations side by side, a column per label."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents.commands import compare, evaluate
from tests.agents.helpers import refusal


@pytest.fixture(scope="module")
def evaluations(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Reverse-v1 n = 1: lqr and zero on 3 episodes from 1000, lqr on 4 from 7000, and the
    zero action on 3 episodes from 7000 in another folder."""
    root = tmp_path_factory.mktemp("compare")
    runs = {
        "test": ["--policy", "lqr", "zero", "--episodes", "3"],
        "fresh": ["--policy", "lqr", "--episodes", "4", "--seed", "7000"],
        "fresh_zero": ["--policy", "zero", "--episodes", "3", "--seed", "7000"],
    }
    for name, argv in runs.items():
        common = ["--n-trailers", "1", "--no-plots", "--out", str(root / name)]
        assert evaluate.main([*argv, *common]) == 0
    return root


def _rate(folder: Path, name: str) -> str:
    document = json.loads((folder / "results.json").read_text())
    (policy,) = [row for row in document["policies"] if row["name"] == name]
    return f"{100 * policy['safe_rate']:.0f}"


def test_a_column_per_label_and_a_row_per_policy(evaluations: Path, tmp_path: Path) -> None:
    out = tmp_path / "table.md"
    argv = [f"test={evaluations / 'test'}", f"fresh={evaluations / 'fresh'}"]
    argv += [f"fresh={evaluations / 'fresh_zero'}", "--out", str(out)]
    assert compare.main(argv) == 0
    lines = out.read_text().splitlines()
    assert lines[0] == "| policy | test | fresh |"
    lqr = f"| lqr | {_rate(evaluations / 'test', 'lqr')} | {_rate(evaluations / 'fresh', 'lqr')} |"
    zero_test, zero_fresh = (
        _rate(evaluations / "test", "zero"),
        _rate(evaluations / "fresh_zero", "zero"),
    )
    assert lines[2:4] == [lqr, f"| zero | {zero_test} | {zero_fresh} |"]
    assert "- fresh: `fresh`, Reverse-v1 (n_trailers=1), 4 episodes, seeds 7000-7003" in lines


def test_refusals_write_nothing(
    evaluations: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "table.md"
    test, fresh = evaluations / "test", evaluations / "fresh"
    assert "expected LABEL=DIR" in refusal(compare.main, [str(test), "--out", str(out)], capsys)
    empty = [f"a={tmp_path}", "--out", str(out)]
    assert "has no results.json" in refusal(compare.main, empty, capsys)
    twice = [f"a={test}", f"a={fresh}", "--out", str(out)]
    assert "lqr is in two evaluations under 'a'" in refusal(compare.main, twice, capsys)
    assert not out.exists()
    out.write_text("kept")
    assert "pass --overwrite" in refusal(compare.main, [f"a={test}", "--out", str(out)], capsys)
    assert out.read_text() == "kept"
