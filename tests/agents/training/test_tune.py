"""``agents.tune``: the objective, the trial entries, a two-trial search, resuming, refusals."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from agents.commands import tune as command
from agents.training.config import load_hyperparams
from agents.training.tune import (
    BEST_HYPERPARAMS,
    BEST_TRIALS,
    MISSING_OPTUNA,
    STUDY_FILE,
    TuneSettings,
    area_over_budget,
    first_reaching,
    read_space,
    trial_entry,
)
from tests.agents.helpers import tiny_ppo_hyperparams

optuna = pytest.importorskip("optuna")

REVERSE = "trailer_env/Reverse-v1"
SPACE = """\
ppo:
  learning_rate: {log_uniform: [1.0e-4, 1.0e-3]}
  n_steps: {categorical: [32, 64]}
  net_arch: {categorical: ["8", "16x16"]}
  log_std_init: {uniform: [-2.0, 0.0]}
"""


def test_objective_is_the_rate_averaged_over_the_budget() -> None:
    assert area_over_budget([0, 50, 100], [0.0, 0.5, 1.0], 100) == pytest.approx(0.5)
    # Past the budget the curve is cut (at 150: rate 1): (50 + 50) / 150.
    assert area_over_budget([0, 100, 200], [0.0, 1.0, 1.0], 150) == pytest.approx(2 / 3)
    # A curve that stops at half the budget counts nothing after it.
    assert area_over_budget([0, 50], [1.0, 1.0], 100) == pytest.approx(0.5)
    assert area_over_budget([], [], 100) == 0.0
    # Over wall time, a trial that ended its steps early keeps its last rate: (25 + 50) / 100.
    assert area_over_budget([0, 50], [0.0, 1.0], 100, hold_last=True) == pytest.approx(0.75)
    assert area_over_budget([0, 200], [0.0, 1.0], 100, hold_last=True) == pytest.approx(0.25)


def test_the_plateau_starts_at_90_percent_of_the_best_rate() -> None:
    assert first_reaching([0.0, 0.5, 0.9, 0.95, 1.0]) == 2
    assert first_reaching([0.0, 0.2, 0.19], share=0.9) == 1
    assert first_reaching([0.0, 0.0]) is None and first_reaching([]) is None


def test_the_pruner_compares_trials_at_the_same_step_or_the_same_time() -> None:
    over_steps = TuneSettings(REVERSE, "ppo", 1, budget=1000)
    over_time = TuneSettings(REVERSE, "ppo", 1, budget=1000, wall_budget=100.0)
    assert over_steps.report_index(3, 55.0) == 3
    # Over wall time, the tenth of the window: a trial evaluating often and one evaluating
    # rarely are compared at 55 s, not at their third evaluation.
    assert over_time.report_index(3, 55.0) == 5 and over_time.report_index(9, 55.0) == 5
    assert over_time.objective([0, 10], [0.0, 50.0], [0.0, 1.0]) == pytest.approx(0.75)


def test_trial_entry_puts_the_policy_keys_into_policy_kwargs() -> None:
    base = {"n_envs": 4, "n_steps": 64, "batch_size": 512, "policy_kwargs": "dict(net_arch=[8])"}
    entry = trial_entry(base, {"net_arch": "32x16", "log_std_init": -0.5, "gamma": 0.99})
    assert entry == {
        "n_envs": 4,
        "n_steps": 64,
        "batch_size": 256,  # cut to one rollout, 64 x 4
        "policy_kwargs": "dict(net_arch=[32, 16], log_std_init=-0.5)",
        "gamma": 0.99,
    }


def test_search_spaces_are_checked(tmp_path: Path) -> None:
    shipped = read_space("ppo_lag")
    assert shipped["lambda_lr"].kind == "log_uniform" and "net_arch" in shipped
    assert set(read_space("td3")) >= {"noise_std", "tau"}
    path = tmp_path / "space.yml"
    for text, message in (
        ("ppo:\n  nonsense: {uniform: [0, 1]}\n", "'nonsense' is not an argument of ppo"),
        ("ppo:\n  gamma: {uniform: [1, 0]}\n", "gamma: uniform needs \\[low, high\\]"),
        ("ppo:\n  ent_coef: {log_uniform: [0, 1]}\n", "log_uniform needs low > 0"),
        ("ppo:\n  net_arch: {categorical: [big]}\n", "net_arch choice 'big'"),
        ("ppo:\n  gamma: {normal: [0, 1]}\n", "gamma must be one of"),
        ("sac:\n  gamma: {uniform: [0, 1]}\n", "has no search space for ppo"),
    ):
        path.write_text(text)
        with pytest.raises(ValueError, match=message):
            read_space("ppo", path)


def _tune(tmp_path: Path, out: Path, *extra: str) -> int:
    return command.main(
        [
            "--env",
            REVERSE,
            "--algo",
            "ppo",
            "--n-trailers",
            "1",
            "--timesteps",
            "1024",
            "--eval-episodes",
            "2",
            "--hyperparams",
            str(tmp_path / "hp"),
            "--space",
            str(tmp_path / "space.yml"),
            "--out",
            str(out),
            "--quiet",
            *extra,
        ]
    )


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def test_two_trials_write_a_study_and_the_winner(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tiny_ppo_hyperparams(tmp_path / "hp", REVERSE, "dict(net_arch=[8], log_std_init=-1.0)")
    (tmp_path / "space.yml").write_text(SPACE)
    out = tmp_path / "search"
    assert _tune(tmp_path, out, "--trials", "2") == 0
    for name in (STUDY_FILE, BEST_TRIALS, BEST_HYPERPARAMS, "search.json"):
        assert (out / name).is_file()
    for trial in ("trial_0000", "trial_0001"):  # normal run folders, with their entry
        assert {"config.json", "evaluations.csv", "final_model.zip", "ppo.yml"} <= {
            path.name for path in (out / "trials" / trial).iterdir()
        }
    table = (out / BEST_TRIALS).read_text()
    assert "trials: 2 complete, 0 pruned, 0 fail" in table
    assert table.count("| learning_rate=") == 2
    # The winner is an entry of an agents/hyperparams file.
    (tmp_path / "winner").mkdir()
    (tmp_path / "winner" / "ppo.yml").write_text((out / BEST_HYPERPARAMS).read_text())
    winner = load_hyperparams("ppo", REVERSE, tmp_path / "winner")
    assert winner.algo_kwargs["n_steps"] in (32, 64) and winner.n_envs == 8
    assert len(winner.algo_kwargs["policy_kwargs"]["net_arch"]) in (1, 2)

    # Refusals write nothing: a finished search without --overwrite, bad arguments,
    # another search's settings, a folder that is not a search.
    before = _snapshot(out)
    capsys.readouterr()
    for extra, message in (
        (["--trials", "3"], "best_trials.md exists (a finished search); pass --overwrite"),
        (["--trials", "0"], "argument --trials: must be >= 1"),
        (["--trials", "3", "--seed", "1", "--overwrite"], "other settings (seed)"),
    ):
        with pytest.raises(SystemExit) as refused:
            _tune(tmp_path, out, *extra)
        assert refused.value.code == 2 and message in capsys.readouterr().err
    assert _snapshot(out) == before
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    with pytest.raises(SystemExit):
        _tune(tmp_path, other, "--trials", "1")
    assert "is not empty and holds no search" in capsys.readouterr().err
    assert [path.name for path in other.iterdir()] == ["notes.txt"]

    # A killed search left a trial running: the resumed search fails it and goes on.
    storage = optuna.storages.JournalStorage(
        optuna.storages.journal.JournalFileBackend(str(out / STUDY_FILE))
    )
    optuna.load_study(study_name="search", storage=storage).ask()
    assert _tune(tmp_path, out, "--trials", "4", "--overwrite") == 0
    states = [t.state.name for t in optuna.load_study(study_name="search", storage=storage).trials]
    assert states == ["COMPLETE", "COMPLETE", "FAIL", "COMPLETE"]
    assert "trials: 3 complete, 0 pruned, 1 fail" in (out / BEST_TRIALS).read_text()


def test_missing_optuna_is_one_line_naming_the_extra(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "optuna", None)  # import optuna raises ImportError
    with pytest.raises(SystemExit) as refused:
        _tune(tmp_path, tmp_path / "search", "--trials", "1")
    assert refused.value.code == 2 and MISSING_OPTUNA in capsys.readouterr().err
    assert "trailer-env[tune]" in MISSING_OPTUNA and not (tmp_path / "search").exists()


def test_a_search_over_wall_time_stops_trials_by_the_clock(tmp_path: Path) -> None:
    from agents.artifacts.curves import read_curve

    tiny_ppo_hyperparams(tmp_path / "hp", REVERSE, "dict(net_arch=[8], log_std_init=-1.0)")
    (tmp_path / "space.yml").write_text(SPACE)
    # A window no trial reaches: every trial trains its 1024 steps and keeps its last
    # rate to the end of the window, so its objective is about that rate.
    long = tmp_path / "long"
    assert _tune(tmp_path, long, "--trials", "1", "--wall-budget", "1e6") == 0
    storage = optuna.storages.JournalStorage(
        optuna.storages.journal.JournalFileBackend(str(long / STUDY_FILE))
    )
    (trial,) = optuna.load_study(study_name="search", storage=storage).trials
    rows = read_curve(
        long / "trials" / "trial_0000" / "evaluations.csv", ("timesteps", "wall_s", "safe_rate")
    )
    assert rows[-1]["timesteps"] >= 1024
    seconds = [row["wall_s"] for row in rows]
    rates = [row["safe_rate"] for row in rows]
    assert trial.value == pytest.approx(area_over_budget(seconds, rates, 1e6, hold_last=True))
    assert trial.user_attrs["wall_s"] == seconds[-1]
    table = (long / BEST_TRIALS).read_text()
    assert "at most 1,024 steps per trial; objective: the validation safe_rate averaged " in table
    assert "averaged over the first 1e+06 s of wall time (area" in table
    # A window shorter than the first evaluation: the trial stops after it, by the clock.
    short = tmp_path / "short"
    assert _tune(tmp_path, short, "--trials", "1", "--wall-budget", "0.001") == 0
    rows = read_curve(short / "trials" / "trial_0000" / "evaluations.csv", ("timesteps",))
    assert [row["timesteps"] for row in rows] == [0]
    # The window is part of the search's settings: another one is another search.
    with pytest.raises(SystemExit):
        _tune(tmp_path, short, "--trials", "2", "--wall-budget", "5", "--overwrite")
