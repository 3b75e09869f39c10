"""The ladder: time to the certified ceiling against n, one point per measured run."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents.commands.ladder import main
from agents.evaluation.ladder import OUTPUTS, Ladder, read_ladder, read_point

REVERSE = "trailer_env/Reverse-v1"
HOST = {
    "benchmark": "reverse_v1_n3_batch8_ppo2048",
    "env_steps_per_s": 231_531.8,
    "ppo_update_s": 0.8067,
    "cpus": 2,
    "torch_threads": 1,
    "load_average": 0.6,
}


def _run(folder: Path, n: object, rows: list[tuple[float, float]], **card: object) -> Path:
    """A run folder: its record and its curve of (wall seconds, safe rate)."""
    folder.mkdir(parents=True)
    record = {"algo": "ppo", "env_id": REVERSE, "env_kwargs": {"n_trailers": n}, "seed": 2}
    (folder / "config.json").write_text(json.dumps({**record, "normalize": None, **card}))
    lines = ["timesteps,wall_s,safe_rate"] + [
        f"{1000 * (k + 1)},{wall},{rate}" for k, (wall, rate) in enumerate(rows)
    ]
    (folder / "evaluations.csv").write_text("\n".join(lines) + "\n")
    return folder


def test_a_run_reaches_the_ceiling_at_its_first_evaluation_within_two_points(
    tmp_path: Path,
) -> None:
    # The committed Reverse-v1 n = 3 certificate's ceiling is 100 %: 0.98 is within 2 points.
    rows = [(60.0, 0.5), (300.0, 0.97), (420.0, 0.98), (600.0, 1.0), (1200.0, 1.0)]
    point = read_point("PPO", _run(tmp_path / "fast", 3, rows, host=HOST))
    assert point.ceiling == pytest.approx(1.0) and point.n_trailers == 3 and point.seed == 2
    assert point.reached_s == 420.0 and point.reached
    assert (point.best_rate, point.best_s, point.last_s) == (1.0, 600.0, 1200.0)
    assert point.host is not None and point.host.env_steps_per_s == 231_531.8
    # Rows after the budget do not count: best within 15 minutes, reached never.
    slow = read_point("PPO", _run(tmp_path / "slow", 3, [(60.0, 0.2), (800.0, 0.5), (901.0, 1.0)]))
    assert slow.reached_s is None and (slow.best_rate, slow.best_s) == (0.5, 800.0)
    assert read_point("PPO", tmp_path / "slow", budget_minutes=16).reached_s == 901.0


def test_a_committed_model_is_read_from_its_card_and_curve() -> None:
    # agents/models/dagger_reverse_v1_n4.csv: 0.52 at 473.0 s, 0.85 at 930.8 s; ceiling 96 %.
    point = read_point("DAgger", Path("agents/models/dagger_reverse_v1_n4.zip"))
    assert point.n_trailers == 4 and point.ceiling == pytest.approx(0.96)
    assert (point.best_rate, point.best_s, point.reached_s) == (0.52, 473.0, None)
    assert point.host is None  # trained before cards recorded the host


def test_what_is_not_one_run_of_one_count_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="one count of trailers"):
        read_point("PPO", _run(tmp_path / "general", [1, 3], [(60.0, 0.5)]))
    with pytest.raises(ValueError, match="neither a run folder nor a model"):
        read_point("PPO", tmp_path / "absent")
    bare = tmp_path / "bare"
    bare.mkdir()
    with pytest.raises(ValueError, match=r"no config\.json"):
        read_point("PPO", bare)
    no_curve = _run(tmp_path / "no_curve", 3, [(1.0, 0.0)])
    (no_curve / "evaluations.csv").unlink()
    with pytest.raises(ValueError, match="no learning curve"):
        read_point("PPO", no_curve)


def test_the_command_writes_the_ladder_refuses_before_writing_and_redraws(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    one = _run(tmp_path / "ppo_n3", 3, [(60.0, 0.5), (420.0, 0.99)], host=HOST)
    two = _run(tmp_path / "sac_n3", 3, [(60.0, 0.1), (700.0, 0.4)])
    out = tmp_path / "ladder"
    assert main(["--method", "PPO", str(one), "--method", "SAC", str(two), "--out", str(out)]) == 0
    table = capsys.readouterr().out
    assert "| 3 | 100 % | 7.0 min (1 of 1) | best 40 % (0 of 1) |" in table
    assert "| PPO | 3 | 2 | 7.0 min | 99 % at 7.0 min | 7.0 min | 232k steps/s" in table
    assert sorted(path.name for path in out.iterdir()) == sorted(OUTPUTS)
    ladder = read_ladder(out)
    assert isinstance(ladder, Ladder) and ladder.methods == ["PPO", "SAC"]
    assert [point.reached_s for point in ladder.points] == [420.0, None]
    written = {name: (out / name).read_bytes() for name in OUTPUTS}
    refusals = [
        ["--method", "PPO", str(one), "--out", str(out)],  # holds a ladder: --overwrite
        ["--method", "PPO", str(one), "--method", "PPO", str(two), "--out", str(out / "x")],
        ["--method", "PPO", str(one), str(tmp_path / "absent"), "--out", str(out / "y")],
        ["--method", "PPO", "--out", str(out / "z")],
        ["--out", str(out / "w")],
    ]
    for argv in refusals:
        with pytest.raises(SystemExit) as refused:
            main(argv)
        assert refused.value.code == 2
    assert "pass --overwrite" in capsys.readouterr().err
    assert {name: (out / name).read_bytes() for name in OUTPUTS} == written
    assert not any((out / name).exists() for name in "xyzw")
    (out / "ladder.md").unlink()
    assert main(["--redraw", "--out", str(out)]) == 0
    assert (out / "ladder.md").read_bytes() == written["ladder.md"]
    (out / "ladder.json").write_text('{"budget_minutes": 15}')
    with pytest.raises(SystemExit):
        main(["--redraw", "--out", str(out)])


def test_update_replaces_one_methods_points_and_keeps_the_others(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    ppo = _run(tmp_path / "ppo_n3", 3, [(60.0, 0.5), (420.0, 0.99)])
    sac = _run(tmp_path / "sac_n3", 3, [(60.0, 0.1), (700.0, 0.4)])
    out = tmp_path / "ladder"
    assert main(["--method", "PPO", str(ppo), "--method", "SAC", str(sac), "--out", str(out)]) == 0
    written = {name: (out / name).read_bytes() for name in OUTPUTS}
    retrained = _run(tmp_path / "sac_n3_again", 3, [(60.0, 0.3), (500.0, 0.9)])
    refusals = [
        ["--update", "--method", "SAC", str(retrained), "--out", str(out)],  # no --overwrite
        ["--update", "--overwrite", "--method", "SAC", str(retrained), "--out", str(tmp_path)],
        [
            "--update",
            "--overwrite",
            "--budget-minutes",
            "20",
            "--method",
            "SAC",
            str(retrained),
            "--out",
            str(out),
        ],
        ["--update", "--redraw", "--out", str(out)],
    ]
    for argv in refusals:
        with pytest.raises(SystemExit) as refused:
            main(argv)
        assert refused.value.code == 2
    capsys.readouterr()
    assert {name: (out / name).read_bytes() for name in OUTPUTS} == written
    argv = ["--update", "--overwrite", "--method", "SAC", str(retrained), "--out", str(out)]
    assert main(argv) == 0
    ladder = read_ladder(out)
    assert ladder.methods == ["PPO", "SAC"]
    assert [(point.method, point.best_rate) for point in ladder.points] == [
        ("PPO", 0.99),
        ("SAC", 0.9),
    ]
    argv = ["--update", "--overwrite", "--method", "SHAC", str(retrained), "--out", str(out)]
    assert main(argv) == 0
    assert read_ladder(out).methods == ["PPO", "SAC", "SHAC"]
