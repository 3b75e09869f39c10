"""benchmarks.timings: first and warm runs, the load, the merged JSON and the docs' table."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from benchmarks import timings

TINY = (
    timings.Timed("hello", ("python", "-c", "print('hello')"), True, "a print"),
    timings.Timed("fails", ("python", "-c", "raise SystemExit(3)"), False, "exit 3"),
)


@pytest.fixture
def tiny(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(timings, "COMMANDS", TINY)
    monkeypatch.setattr(timings, "NAMES", tuple(command.name for command in TINY))


def test_quick_commands_are_measured_and_written(tiny: None, tmp_path: Path) -> None:
    assert timings.main(["--out", str(tmp_path)]) == 0
    (record,) = json.loads((tmp_path / "timings.json").read_text())
    assert record["name"] == "hello"
    assert record["command"] == "python -c 'print('\"'\"'hello'\"'\"')'"
    for run in ("first", "warm"):
        assert record[run]["status"] == 0
        assert 0.0 <= record[run]["seconds"] < 60.0
        assert record[run]["load"] >= 0.0
    table = (tmp_path / "timings.md").read_text()
    assert "| a print |" in table
    assert "not measured yet: `python -m benchmarks.timings --only fails`" in table
    assert sorted(path.name for path in tmp_path.iterdir()) == ["timings.json", "timings.md"]


def test_a_later_run_replaces_only_its_commands(tiny: None, tmp_path: Path) -> None:
    assert timings.main(["--out", str(tmp_path)]) == 0
    first = json.loads((tmp_path / "timings.json").read_text())
    assert timings.main(["--out", str(tmp_path), "--only", "fails"]) == 1  # it exits 3
    records = json.loads((tmp_path / "timings.json").read_text())
    assert [record["name"] for record in records] == ["hello", "fails"]
    assert records[0] == first[0]
    assert records[1]["first"]["status"] == 3
    assert "| exit 3 | failed (exit 3) | failed (exit 3) |" in (tmp_path / "timings.md").read_text()


def test_the_numba_cache_is_fresh_and_shared_by_the_two_runs(
    tiny: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    probe = timings.Timed(
        "cache", ("python", "-c", "import os; print(os.environ['NUMBA_CACHE_DIR'])"), True
    )
    seen = []
    original = timings.run_once

    def spy(argv, work, cache, timeout):  # type: ignore[no-untyped-def]
        seen.append((cache, cache.exists(), work))
        return original(argv, work, cache, timeout)

    monkeypatch.setattr(timings, "run_once", spy)
    record = timings.measure(probe)
    assert record["first"]["status"] == record["warm"]["status"] == 0
    (cache_a, existed_a, work_a), (cache_b, _, work_b) = seen
    assert cache_a == cache_b and not existed_a  # empty for the first run
    assert work_a != work_b and not work_a.exists()  # removed afterwards


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--only", "nonsense"], "argument --only: invalid choice: 'nonsense'"),
        (["--only", "hello", "--all"], "not allowed with argument"),
        (["--timeout", "0"], "argument --timeout: must be > 0"),
    ],
)
def test_bad_arguments_exit_2_and_write_nothing(
    tiny: None, tmp_path: Path, argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as raised:
        timings.main([*argv, "--out", str(tmp_path / "t")])
    assert raised.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "t").exists()


def test_every_documented_command_has_a_name() -> None:
    assert timings.NAMES == (
        "first-step",
        "compile",
        "main",
        "evaluate-video",
        "evaluate-mpc",
        "main-retrain",
        "main-planner",
        "certify",
        "report",
    )
    assert [command.name for command in timings.COMMANDS if command.quick] == [
        "first-step",
        "compile",
        "main",
        "evaluate-video",
    ]
