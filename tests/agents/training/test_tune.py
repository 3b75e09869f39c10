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
    area_over_budget,
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

    # A killed search left a trial running: the next session fails it and goes on.
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
