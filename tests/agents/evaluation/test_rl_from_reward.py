"""The RL-from-reward table: the final plateau rule and the table's rows."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from agents.commands.rl_from_reward import main
from agents.evaluation.learning_curves import final_plateau, plateau
from agents.evaluation.rl_from_reward import RunScore, markdown
from tests.agents.helpers import tiny_ppo_hyperparams

STEPS = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10]


def test_a_flat_start_before_the_jump_is_not_the_final_plateau() -> None:
    values = [0.0, 0.0, 0.0, 0.0, 0.0, 0.44, 0.86, 0.94, 0.96, 0.98, 0.96]
    assert plateau(STEPS, values, 5, 0.05).start == 0  # type: ignore[union-attr]
    settled = final_plateau(STEPS, values, 3, 0.05)
    assert settled is not None
    assert settled.start == 7  # 0.94 is within 0.05 of the last three's mean, 0.86 is not
    assert settled.level == pytest.approx((0.96 + 0.98 + 0.96) / 3)


def test_a_curve_climbing_at_its_end_has_no_final_plateau() -> None:
    assert final_plateau(STEPS, [0.0] * 6 + [0.2, 0.4, 0.6, 0.8, 0.9], 3, 0.05) is None
    assert final_plateau(STEPS[:2], [0.1, 0.1], 3, 0.05) is None
    with pytest.raises(ValueError, match="strictly increasing"):
        final_plateau([0, 0, 1], [0.1, 0.1, 0.1], 2, 0.05)


def _score(seed: int, kept: float, final: float, flat: float | None) -> RunScore:
    return RunScore(
        run=f"ppo_s{seed}",
        env_id="trailer_env/Reverse-v1",
        n_trailers=2,
        algo="ppo",
        seed=seed,
        budget=10_000_000,
        wall_s=600.0,
        metric="safe_rate",
        plateau_step=flat,
        plateau_level=None if flat is None else 0.97,
        final_validation=0.96,
        best_validation=1.0,
        kept_at=6_500_000,
        kept_test=kept,
        kept_fresh=kept,
        final_test=final,
        final_fresh=final,
    )


def test_the_table_has_a_row_per_run_and_the_seed_mean() -> None:
    text = markdown([_score(0, 0.96, 0.98, 4e6), _score(1, 0.98, 1.0, None)], 7000, 200)
    assert "#### Reverse-v1, n = 2" in text
    assert "| ppo seed 0 | 10.0M | 10.0 min | 4.0M (0.97) | - | 6.5M | 96 / 98 | 96 / 98 |" in text
    assert "| ppo seed 1 | 10.0M | 10.0 min | not flat at the end | - | 6.5M | 98 / 100 |" in text
    assert "| **ppo mean ± sd (2 seeds)** | | 10 ± 0 min | | | | 97 ± 1 / 99 ± 1 |" in text
    rising = replace(
        _score(2, 0.9, 0.9, None), trend_change=0.12, trend_se=0.04, trend_evaluations=8
    )
    assert "| not flat at the end | +0.12 ± 0.04, rising | 6.5M |" in markdown([rising], 7000, 200)
    assert "fresh: seeds 7000..7199" in text


def test_a_kept_rows_trend_comes_from_its_kept_curve(tmp_path: Path) -> None:
    from agents.artifacts.curves import CURVE_COLUMNS, write_curve
    from agents.evaluation.rl_from_reward import _with_trend, curve_folder

    old = _score(0, 0.96, 0.98, None)
    assert _with_trend(old, tmp_path) == old  # no kept curve: left as it was
    kept = curve_folder(tmp_path, old)
    kept.mkdir(parents=True)
    config = {"env_id": old.env_id, "algo": "ppo", "env_kwargs": {"n_trailers": 2}, "seed": 0}
    (kept / "config.json").write_text(json.dumps(config))
    rows = [
        {**dict.fromkeys(CURVE_COLUMNS, 0.0), "timesteps": 1e6 * i, "safe_rate": 0.5 + 0.01 * i}
        for i in range(12)
    ]
    write_curve(kept / "evaluations.csv", rows, CURVE_COLUMNS)
    filled = _with_trend(old, tmp_path)  # the last third of 0..11M: 8M to 11M, then 7M
    assert filled.trend_change == pytest.approx(0.04, abs=1e-12)
    assert filled.trend_se == pytest.approx(0.0, abs=1e-12)
    assert filled.trend_text() == "+0.04 ± 0.00, rising"
    assert _with_trend(filled, tmp_path) == filled


def test_refusals_write_nothing(tmp_path: Path) -> None:
    with pytest.raises(SystemExit):
        main([str(tmp_path), "--out", str(tmp_path / "out")])  # no run folder
    with pytest.raises(SystemExit):
        main([str(tmp_path), "--fresh-seed", "1050"])  # overlaps the test seeds
    with pytest.raises(SystemExit):
        main([str(tmp_path), "--fresh-episodes", "0"])
    assert not (tmp_path / "out").exists()


def test_a_generalists_run_is_refused_by_name(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import json

    run = tmp_path / "general"
    run.mkdir()
    config = {"env_id": "trailer_env/Reverse-v1", "algo": "ppo", "seed": 0,
              "env_kwargs": {"n_trailers": [1, 3]}}  # fmt: skip
    (run / "config.json").write_text(json.dumps(config))
    (run / "evaluations.csv").write_text("timesteps,wall_s,safe_rate\n0,0.0,0.0\n")
    for name in ("best_model.zip", "final_model.zip"):
        (run / name).write_bytes(b"")
    with pytest.raises(SystemExit) as refused:
        main([str(run), "--out", str(tmp_path / "out")])
    assert refused.value.code == 2
    assert "Reverse-v1 n = 1-3 is one policy for a range of n" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_two_tiny_runs_are_scored_and_the_selected_seed_exported(tmp_path: Path) -> None:
    import json

    from agents.commands import train

    tiny_ppo_hyperparams(tmp_path / "hp", "trailer_env/Coast-v0")
    for seed in (0, 1):
        assert (
            train.main(
                [
                    "--env",
                    "trailer_env/Coast-v0",
                    "--algo",
                    "ppo",
                    "--n-trailers",
                    "1",
                    "--hyperparams",
                    str(tmp_path / "hp"),
                    "--run-dir",
                    str(tmp_path / f"runs/s{seed}"),
                    "--timesteps",
                    "1024",
                    "--eval-freq",
                    "512",
                    "--eval-episodes",
                    "2",
                    "--seed",
                    str(seed),
                    "--no-progress",
                    "--quiet",
                ]
            )
            == 0
        )
    out, model = tmp_path / "table", tmp_path / "models" / "tiny.zip"
    argv = [str(tmp_path / "runs"), "--out", str(out), "--fresh-episodes", "3"]
    assert main([*argv, "--export", str(model)]) == 0
    document = json.loads((out / "rl_from_reward.json").read_text())
    assert [run["seed"] for run in document["runs"]] == [0, 1]
    assert {run["budget"] for run in document["runs"]} == {1024}
    # The tiny runs' one hidden layer of 8 is in the recipe's name (not 64 x 64).
    assert "| **ppo (8) mean ± sd (2 seeds)** |" in (out / "rl_from_reward.md").read_text()
    # The curves outlive the run folders: byte copies, named by scene, n, recipe and seed,
    # from which agents.curves redraws the chart.
    kept = sorted(p.name for p in (out / "rl_runs").iterdir())
    assert kept == ["coast_v0_n1_ppo_8_s0", "coast_v0_n1_ppo_8_s1"]
    for seed in (0, 1):
        for name in ("config.json", "evaluations.csv"):
            copy = out / "rl_runs" / f"coast_v0_n1_ppo_8_s{seed}" / name
            assert copy.read_bytes() == (tmp_path / f"runs/s{seed}" / name).read_bytes()
    from agents.commands import curves

    assert curves.main([str(out / "rl_runs"), "--out", str(tmp_path / "chart")]) == 0
    assert (
        "| Coast-v0, n = 1, ppo (8) | success_rate | 2 |"
        in (tmp_path / "chart" / "learning_curves.md").read_text()
    )
    card = json.loads(model.with_suffix(".json").read_text())
    assert card["selection"]["chosen_seed"] in (0, 1)
    assert card["seed"] == card["selection"]["chosen_seed"]
    assert sorted(p.name for p in (tmp_path / "models" / "seeds").glob("*.zip")) == [
        "tiny_s0.zip",
        "tiny_s1.zip",
    ]
    before = (out / "rl_from_reward.md").read_bytes()
    with pytest.raises(SystemExit):  # an existing table without --overwrite
        main(argv)
    assert (out / "rl_from_reward.md").read_bytes() == before
    # --update re-scores the runs given and keeps the table's other rows as scored; a
    # run is its scene, n, recipe and seed, so seed 1 scored under another folder name
    # is replaced, not counted twice.
    document["runs"].append({**document["runs"][0], "run": "gone", "seed": 7, "kept_test": 0.5})
    document["runs"][1]["run"] = "s1_under_another_name"
    (out / "rl_from_reward.json").write_text(json.dumps(document))
    assert main([str(tmp_path / "runs" / "s1"), *argv[1:], "--update"]) == 0
    updated = json.loads((out / "rl_from_reward.json").read_text())
    assert [(run["run"], run["seed"]) for run in updated["runs"]] == [
        ("s0", 0),
        ("s1", 1),
        ("gone", 7),
    ]
    assert updated["runs"][2]["kept_test"] == 0.5
    assert "| ppo (8) seed 7 |" in (out / "rl_from_reward.md").read_text()
    before = (out / "rl_from_reward.json").read_bytes()
    with pytest.raises(SystemExit):  # scored on other fresh episodes: refused
        main([str(tmp_path / "runs" / "s1"), *argv[1:3], "--fresh-episodes", "4", "--update"])
    assert (out / "rl_from_reward.json").read_bytes() == before


def test_the_tables_document_is_read_field_by_field(tmp_path: Path) -> None:
    from agents.evaluation.rl_from_reward import RewardTable, kept_scores

    table = RewardTable(7000, 200, (_score(0, 0.96, 0.98, None),))
    path = tmp_path / "rl_from_reward.json"
    path.write_text(json.dumps(table.to_json()))
    assert RewardTable.from_json(json.loads(path.read_text())) == table
    assert kept_scores(path, 7000, 200) == [table.runs[0]]
    document = table.to_json()
    document["runs"][0]["kept_tset"] = 0.5  # a misspelt field is refused, named
    path.write_text(json.dumps(document))
    with pytest.raises(ValueError, match="kept_tset"):
        kept_scores(path, 7000, 200)
