"""Learning curves over seeds: the plateau rule, the bands, the chart and table, the command."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from agents.artifacts.curves import CURVE_COLUMNS, write_curve
from agents.commands import curves
from agents.evaluation.learning_curves import (
    CHART_FILE,
    TABLE_FILE,
    Plateau,
    bands_overlap,
    group_runs,
    is_rising,
    plateau,
    read_run,
    rise_text,
    seed_band,
    student_t,
    trend,
    write_learning_curves,
)

REVERSE = "trailer_env/Reverse-v1"
STEPS = [0, 100, 200, 300, 400, 500, 600, 700]


def test_plateau_is_the_first_flat_window() -> None:
    values = [0.1, 0.3, 0.5, 0.62, 0.6, 0.61, 0.6, 0.9]
    # (0.5, 0.62, 0.6) spreads 0.07 from its mean; (0.62, 0.6, 0.61) only 0.01.
    found = plateau(STEPS, values, 3, 0.02)
    assert found == Plateau(step=500.0, start=300.0, level=pytest.approx(0.61))
    assert plateau(STEPS, values, 4, 0.02) == Plateau(600.0, 300.0, pytest.approx(0.6075))
    assert plateau(STEPS, values, 3, 0.0) is None
    assert plateau(STEPS[:2], values[:2], 3, 1.0) is None  # fewer evaluations than the window
    assert plateau([0, 1], [0.7, 0.7], 2, 0.0) == Plateau(1.0, 0.0, 0.7)


@pytest.mark.parametrize(
    ("args", "error", "message"),
    [
        ((STEPS, [0.0] * 8, 1, 0.1), ValueError, "window must be >= 2 evaluations, got 1"),
        ((STEPS, [0.0] * 8, 2.0, 0.1), TypeError, "window must be an integer, got float"),
        ((STEPS, [0.0] * 8, 2, -0.1), ValueError, "eps must be a finite number >= 0"),
        ((STEPS, [0.0] * 8, 2, "0.1"), TypeError, "eps must be a number, got str"),
        ((STEPS, [0.0] * 7, 2, 0.1), ValueError, "1-D of one length"),
        (([0, 200, 100], [0.0] * 3, 2, 0.1), ValueError, "strictly increasing"),
    ],
)
def test_plateau_refuses_bad_input(args: tuple, error: type, message: str) -> None:  # type: ignore[type-arg]
    with pytest.raises(error, match=message):
        plateau(*args)


def test_the_trend_fits_the_last_third_of_the_curve() -> None:
    steps = np.arange(12) * 25_000.0
    # A line: its rise over the fitted end, exactly, with no error. The last third
    # (from 183,333 steps) holds 4 evaluations, so the last 5 are fitted.
    line = trend(steps, 0.5 + 0.02 * np.arange(12))
    assert line is not None and (line.start, line.end, line.evaluations) == (175_000, 275_000, 5)
    assert line.change == pytest.approx(0.08, abs=1e-12) and line.se == pytest.approx(0, abs=1e-12)
    assert line.rising and line.text() == "+0.08 ± 0.00, rising"
    # Alternating noise after a climb: the last third (x >= 10 of 0..15) is six
    # evaluations 0.8, 0.9, ...: slope 0.15 / 17.5 per evaluation, rise 3 / 70 over the
    # window, residual variance (0.015 - 0.15**2 / 17.5) / 4: no rise.
    flat = trend(np.arange(16.0), [0.0, 0.3, 0.5, 0.6] + [0.8, 0.9] * 6)
    assert flat is not None and flat.evaluations == 6 and not flat.rising
    assert flat.change == pytest.approx(3 / 70, rel=1e-12)
    assert flat.se == pytest.approx(5 * np.sqrt((0.015 - 0.15**2 / 17.5) / 4 / 17.5), rel=1e-12)
    assert flat.text() == "+0.04 ± 0.07"
    # A run evaluated seldom that rose and then sat: its end is flat (ten evaluations
    # back would span the rise and call it rising).
    risen = [0.0, 0.0, 0.0, 0.5, 0.9, 0.96, 0.95, 0.96, 0.96, 0.95, 0.96]
    end = trend(np.arange(11) * 200_000.0, risen)
    assert end is not None and end.start == 1_200_000 and not end.rising
    # Five points that happen to line up: 2.4 standard errors is a climb by the normal
    # quantile, not by Student's t on 3 degrees of freedom (3.18).
    assert not is_rising(0.024, 0.01, 5) and is_rising(0.024, 0.01, 30)
    assert rise_text(0.024, 0.01, 5) == "+0.02 ± 0.01"
    assert trend(steps[:4], np.zeros(4)) is None  # fewer evaluations than the minimum
    with pytest.raises(ValueError, match="minimum must be >= 3"):
        trend(steps, np.zeros(12), minimum=2)
    with pytest.raises(ValueError, match=r"fraction must be in \(0, 1\]"):
        trend(steps, np.zeros(12), fraction=0.0)
    with pytest.raises(TypeError, match="minimum must be an integer"):
        trend(steps, np.zeros(12), minimum=3.0)  # type: ignore[arg-type]


def test_student_t_matches_its_table_and_tends_to_the_normal() -> None:
    assert (student_t(1), student_t(3), student_t(30)) == (12.706, 3.182, 2.042)
    # Tabulated t(40) = 2.021, t(60) = 2.000, t(120) = 1.980 (three decimals).
    for dof, tabulated in ((40, 2.021), (60, 2.000), (120, 1.980)):
        assert student_t(dof) == pytest.approx(tabulated, abs=5e-4)
    assert student_t(10**9) == pytest.approx(1.959964, abs=1e-6)
    with pytest.raises(ValueError, match="dof must be >= 1"):
        student_t(0)


def make_run(
    folder: Path,
    seed: int,
    rates: list[float],
    algo: str = "ppo",
    n: int = 2,
    wall_per_eval: float = 10.0,
    wall_start: float = 0.0,
) -> Path:
    """A synthetic run folder: config.json and evaluations.csv with ``rates`` as safe_rate."""
    folder.mkdir(parents=True)
    config = {"env_id": REVERSE, "algo": algo, "env_kwargs": {"n_trailers": n}, "seed": seed}
    (folder / "config.json").write_text(json.dumps(config))
    rows = [
        {
            **dict.fromkeys(CURVE_COLUMNS, 0.0),
            "timesteps": step,
            "wall_s": wall_start + wall_per_eval * i,
            "safe_rate": rate,
        }
        for i, (step, rate) in enumerate(zip(STEPS, rates, strict=False))
    ]
    write_curve(folder / "evaluations.csv", rows, CURVE_COLUMNS)
    return folder


def test_groups_and_bands_over_seeds(tmp_path: Path) -> None:
    a = read_run(make_run(tmp_path / "a", 0, [0.0, 0.2, 0.4, 0.6]))
    b = read_run(make_run(tmp_path / "b", 1, [0.0, 0.4, 0.6, 0.8], wall_per_eval=20.0))
    c = read_run(make_run(tmp_path / "c", 0, [0.1, 0.1], algo="ppo_lag"))
    groups = group_runs([b, c, a])
    assert list(groups) == [(REVERSE, 2, "ppo"), (REVERSE, 2, "ppo_lag")]
    assert [run.seed for run in groups[(REVERSE, 2, "ppo")]] == [0, 1]
    band = seed_band(groups[(REVERSE, 2, "ppo")])
    np.testing.assert_allclose(band.x, [0, 100, 200, 300])
    np.testing.assert_allclose(band.mean, [0.0, 0.3, 0.5, 0.7])
    np.testing.assert_allclose(band.low, [0.0, 0.2, 0.4, 0.6])
    np.testing.assert_allclose(band.high, [0.0, 0.4, 0.6, 0.8])
    # Against wall time: a runs to 30 s, b to 60 s; the grid stops at 30 s, b interpolated.
    wall = seed_band(groups[(REVERSE, 2, "ppo")], "wall_s")
    np.testing.assert_allclose(wall.x, [0, 10, 20, 30])
    np.testing.assert_allclose(wall.mean, [0.0, 0.2, 0.4, 0.55])  # b: 0.2, 0.4, 0.5 at 10-30 s
    with pytest.raises(ValueError, match="two runs of one seed"):
        group_runs([a, read_run(make_run(tmp_path / "a2", 0, [0.5]))])
    with pytest.raises(ValueError, match="axis must be one of"):
        seed_band([a], "episodes")
    # A shaped run of the same seed is another recipe, not a second folder of one run.
    shaped_dir = make_run(tmp_path / "shaped", 0, [0.3])
    config = json.loads((shaped_dir / "config.json").read_text())
    (shaped_dir / "config.json").write_text(json.dumps({**config, "shaping": {"potential": "lqr"}}))
    shaped = read_run(shaped_dir)
    assert shaped.algo == "ppo + lqr shaping"
    assert list(group_runs([a, shaped])) == [(REVERSE, 2, "ppo"), (REVERSE, 2, "ppo + lqr shaping")]
    # So is a run with state-dependent exploration (PPO's argument; SAC's policy_kwargs).
    for name, hyperparams in [
        ("sde", {"use_sde": True, "sde_sample_freq": 4}),
        ("sac_sde", {"policy_kwargs": {"net_arch": [64, 64], "use_sde": True}}),
        ("sac_plain", {"policy_kwargs": {"use_sde": False}}),
    ]:
        folder = make_run(tmp_path / name, 0, [0.3])
        config = json.loads((folder / "config.json").read_text())
        config.update(hyperparams=hyperparams, shaping={"potential": "lqr"})
        (folder / "config.json").write_text(json.dumps(config))
        expected = "ppo + lqr shaping" if name == "sac_plain" else "ppo (gSDE) + lqr shaping"
        assert read_run(folder).algo == expected


def test_seeds_without_a_common_wall_range_are_drawn_one_by_one(tmp_path: Path) -> None:
    # A run whose first evaluation waited for a kernel compile can start after a short
    # run ended: no mean against wall time, but the chart is still written.
    runs = [
        read_run(make_run(tmp_path / "s0", 0, [0.1, 0.5, 0.7], wall_per_eval=0.1)),
        read_run(make_run(tmp_path / "s1", 1, [0.2, 0.6, 0.9], wall_start=24.0)),
    ]
    assert bands_overlap(runs, "timesteps") and not bands_overlap(runs, "wall_s")
    with pytest.raises(ValueError, match=r"wall_s ranges do not overlap \(24 > 0.2\)"):
        seed_band(runs, "wall_s")
    np.testing.assert_allclose(seed_band(runs).mean, [0.15, 0.55, 0.8])
    chart, table = write_learning_curves(runs, tmp_path / "out", window=3, eps=0.02)
    assert chart.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (
        table.read_text()
        .splitlines()[-1]
        .startswith("| Reverse-v1, n = 2, ppo | safe_rate | 2 | 0.80 ± 0.10 (0.70-0.90) |")
    )


def test_chart_and_table_are_written_and_not_overwritten(tmp_path: Path) -> None:
    runs = [
        read_run(make_run(tmp_path / "s0", 0, [0.1, 0.5, 0.7, 0.72, 0.71, 0.7])),
        read_run(make_run(tmp_path / "s1", 1, [0.2, 0.6, 0.9, 0.8, 0.6, 0.9])),
    ]
    out = tmp_path / "out"
    levels = {(REVERSE, 2, "ppo"): {"lqr": 0.62, "ceiling": 0.98}}
    chart, table = write_learning_curves(runs, out, window=3, eps=0.02, levels=levels)
    assert chart.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and chart.name == CHART_FILE
    lines = table.read_text().splitlines()
    assert lines[0].startswith(
        "Plateau: where each seed settled for good, at that level: its last 3"
    )
    assert lines[-1] == (
        "| Reverse-v1, n = 2, ppo | safe_rate | 2 | 0.80 ± 0.10 (0.70-0.90) | "
        "0.81 ± 0.09 (0.72-0.90) | s0: 200 (0.71); s1: not flat at the end | "
        "s0: +0.16 ± 0.10; s1: +0.12 ± 0.21 | "
        "500 | 50 | lqr 0.62, ceiling 0.98 |"
    )
    before = table.read_text()
    with pytest.raises(ValueError, match=r"learning_curves\.png exists; pass --overwrite"):
        write_learning_curves(runs[:1], out, window=3, eps=0.02)
    assert table.read_text() == before
    write_learning_curves(runs[:1], out, window=3, eps=0.02, overwrite=True)
    assert "| 1 |" in table.read_text()


def test_command_writes_and_refuses(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    runs = tmp_path / "runs"
    make_run(runs / "s0", 0, [0.1, 0.5, 0.7, 0.7])
    make_run(runs / "s1", 1, [0.3, 0.5, 0.7, 0.7])
    out = tmp_path / "out"
    # A folder of runs; Reverse-v1 n = 2 has a committed certificate: its ceiling is drawn.
    assert (
        curves.main([str(runs), "--out", str(out), "--plateau", "2,0.0", "--level", "lqr=0.5"]) == 0
    )
    text = (out / TABLE_FILE).read_text()
    assert "s0: 200 (0.70); s1: 200 (0.70)" in text
    assert "certified ceiling (test starts) 1.00, lqr 0.50" in text
    before = {path.name: path.read_bytes() for path in out.iterdir()}
    capsys.readouterr()
    for argv, message in (
        ([str(runs)], "learning_curves.png exists; pass --overwrite"),
        ([str(tmp_path / "none")], "is not a folder"),
        ([str(out)], "is not a run folder and holds none"),
        ([str(runs), "--plateau", "1,0.1"], "expected WINDOW,EPS"),
        ([str(runs), "--level", "lqr=1.5"], "expected NAME=RATE with a rate in"),
    ):
        with pytest.raises(SystemExit) as refused:
            curves.main([*argv, "--out", str(out)])
        assert refused.value.code == 2 and message in capsys.readouterr().err
    assert {path.name: path.read_bytes() for path in out.iterdir()} == before
    (runs / "s1" / "evaluations.csv").write_text("timesteps,wall_s\n0,0\n")
    with pytest.raises(SystemExit):
        curves.main([str(runs), "--out", str(tmp_path / "fresh")])
    assert "lacks ['safe_rate']" in capsys.readouterr().err
    assert not (tmp_path / "fresh").exists()


def test_a_generalists_range_is_its_own_group_without_a_ceiling(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    general = make_run(tmp_path / "general", 0, [0.0, 0.3, 0.31, 0.3])
    config = json.loads((general / "config.json").read_text())
    config["env_kwargs"] = {"n_trailers": [1, 3], "randomize": "mismatch20"}
    (general / "config.json").write_text(json.dumps(config))
    runs = [read_run(general), read_run(make_run(tmp_path / "two", 0, [0.5]))]
    assert runs[0].n_trailers == (1, 3)
    assert list(group_runs(runs)) == [(REVERSE, (1, 3), "ppo (mismatch20)"), (REVERSE, 2, "ppo")]
    assert list(curves.levels_of(runs, [("lqr", 0.69)], ceiling=True).values()) == [
        {"lqr": 0.69},  # no certificate for a range
        {"certified ceiling (test starts)": 1.0, "lqr": 0.69},
    ]
    _, table = write_learning_curves(runs[:1], tmp_path / "out", window=3, eps=0.02)
    assert (
        table.read_text()
        .splitlines()[-1]
        .startswith("| Reverse-v1, n = 1-3, ppo (mismatch20) | safe_rate |")
    )
    by_row = make_run(tmp_path / "by_row", 0, [0.0, 0.33])  # the same seed, another recipe
    row_config = json.loads((by_row / "config.json").read_text())
    row_config["env_kwargs"] = {"n_trailers": [1, 3], "trailer_draw": "row"}
    (by_row / "config.json").write_text(json.dumps(row_config))
    assert list(group_runs([runs[0], read_run(by_row)])) == [
        (REVERSE, (1, 3), "ppo (mismatch20)"),
        (REVERSE, (1, 3), "ppo (n by row)"),
    ]
    config["env_kwargs"]["n_trailers"] = [3, 1]
    (general / "config.json").write_text(json.dumps(config))
    with pytest.raises(ValueError, match="n_trailers' must be an integer or a pair"):
        read_run(general)
    config["env_kwargs"]["n_trailers"] = 0
    (general / "config.json").write_text(json.dumps(config))
    with pytest.raises(ValueError, match="n_trailers must be an integer or a range"):
        read_run(general)
