"""``agents.tune`` before it writes: a journal cut by a kill is recovered, a damaged one
refused untouched; a search space is checked whole against the algorithms' bounds; a
PPO-Lagrangian entry out of its bounds is refused by ``agents.train`` before any file."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents.algorithms.bounds import argument_problem
from agents.artifacts import files
from agents.commands import train as train_command
from agents.commands import tune as command
from agents.training.config import load_hyperparams
from agents.training.tune import (
    BEST_TRIALS,
    SETTINGS_FILE,
    STUDY_FILE,
    TuneSettings,
    intact_journal_length,
    read_space,
)
from tests.agents.helpers import tiny_ppo_hyperparams

optuna = pytest.importorskip("optuna")

REVERSE = "trailer_env/Reverse-v1"
SPACE = "ppo:\n  learning_rate: {log_uniform: [1.0e-4, 1.0e-3]}\n"
CUT = b'{"op_code":4,"worker_id":"a-b","trial_id":2,"sta'


def _tune(tmp_path: Path, out: Path, *extra: str) -> int:
    return command.main(
        [
            "--env", REVERSE, "--algo", "ppo", "--n-trailers", "1", "--timesteps", "1024",
            "--eval-episodes", "2", "--hyperparams", str(tmp_path / "hp"),
            "--space", str(tmp_path / "space.yml"), "--out", str(out), "--quiet", *extra,
        ]
    )  # fmt: skip


def _study(tmp_path: Path) -> Path:
    """A search folder as a killed search leaves it: its settings and a journal of two
    complete trials (made without training)."""
    tiny_ppo_hyperparams(tmp_path / "hp", REVERSE)
    (tmp_path / "space.yml").write_text(SPACE)
    out = tmp_path / "search"
    out.mkdir()
    settings = TuneSettings(
        REVERSE, "ppo", 1, 1024, eval_episodes=2, hyperparams=tmp_path / "hp",
        space=tmp_path / "space.yml",
    )  # fmt: skip
    files.write_json(out / SETTINGS_FILE, settings.document())
    storage = optuna.storages.JournalStorage(
        optuna.storages.journal.JournalFileBackend(str(out / STUDY_FILE))
    )
    study = optuna.create_study(study_name="search", storage=storage, direction="maximize")
    for value in (0.25, 0.5):
        study.tell(study.ask(), value)
    return out


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def test_a_record_cut_by_a_kill_is_dropped_and_the_search_resumes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = _study(tmp_path)
    journal = out / STUDY_FILE
    intact = journal.read_bytes()
    journal.write_bytes(intact + CUT)
    assert intact_journal_length(journal) == len(intact)
    assert _tune(tmp_path, out, "--trials", "2") == 0  # the study holds its two trials
    recovered = journal.read_bytes()
    assert recovered.startswith(intact) and CUT not in recovered  # the resumed study appends
    assert "dropped its last record, cut by a kill (48 bytes)" in capsys.readouterr().err
    assert "trials: 2 complete, 0 pruned, 0 fail" in (out / BEST_TRIALS).read_text()
    for line in journal.read_bytes().splitlines():
        assert isinstance(json.loads(line), dict)


def test_a_damaged_journal_is_refused_and_left_as_it_is(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = _study(tmp_path)
    journal = out / STUDY_FILE
    first, rest = journal.read_bytes().split(b"\n", 1)
    journal.write_bytes(first + b"\n" + CUT + b"\n" + rest + CUT)
    before = _snapshot(out)
    capsys.readouterr()
    with pytest.raises(SystemExit) as refused:
        _tune(tmp_path, out, "--trials", "3")
    assert refused.value.code == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert "is damaged: its record 2 is not a JSON object" in error
    assert "Traceback" not in error
    assert _snapshot(out) == before


@pytest.mark.parametrize(
    ("space", "message"),
    [
        ("ppo:\n  batch_size: {categorical: [0]}\n", "batch_size must be an integer >= 2, got 0"),
        (
            "ppo:\n  gamma: {categorical: [0.99, 1.5]}\n",
            r"gamma must be a finite number in \[0, 1\], got 1.5",
        ),
        (
            "ppo:\n  gamma: {uniform: [0.9, 1.2]}\n",
            r"gamma must be a finite number in \[0, 1\], got 1.2",
        ),
        ("ppo:\n  n_epochs: {uniform: [1, 10]}\n", "n_epochs takes integers"),
        ("ppo:\n  n_steps: {int: [0, 64]}\n", "n_steps must be an integer >= 1, got 0"),
        ("ppo:\n  seed: {int: [0, 3]}\n", "'seed' is not an argument of ppo that a search may set"),
        (
            "ppo:\n  net_arch: {categorical: ['8', '100000x100000']}\n",
            "net_arch choice '100000x100000'",
        ),
        (
            "ppo_lag:\n  lambda_lr: {categorical: [0.0, 0.1]}\n",
            r"lambda_lr must be a finite number > 0, got 0.0",
        ),
        (
            "sac:\n  tau: {uniform: [0.0, 0.02]}\n",
            r"tau must be a finite number in \(0, 1\], got 0.0",
        ),
    ],
)
def test_a_search_space_is_checked_whole(tmp_path: Path, space: str, message: str) -> None:
    path = tmp_path / "space.yml"
    path.write_text(space)
    with pytest.raises(ValueError, match=message):
        read_space(space.split(":", 1)[0], path)


def test_a_bad_search_space_writes_no_study(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tiny_ppo_hyperparams(tmp_path / "hp", REVERSE)
    (tmp_path / "space.yml").write_text("ppo:\n  batch_size: {categorical: [0]}\n")
    out = tmp_path / "search"
    with pytest.raises(SystemExit) as refused:
        _tune(tmp_path, out, "--trials", "1")
    assert refused.value.code == 2
    assert "argument --space:" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("cost_limit: -1", "cost_limit must be a finite number >= 0, got -1"),
        ("lambda_lr: 0", "lambda_lr must be a finite number > 0, got 0"),
        ("lambda_init: -1", "lambda_init must be a finite number >= 0, got -1"),
        ("gamma: 1.5", r"gamma must be a finite number in \[0, 1\], got 1.5"),
    ],
)
def test_ppo_lagrangian_out_of_bounds_is_refused_before_a_run_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], line: str, message: str
) -> None:
    folder = tmp_path / "hp"
    folder.mkdir()
    (folder / "ppo_lag.yml").write_text(
        f"{REVERSE}:\n  n_envs: 2\n  n_steps: 16\n  batch_size: 32\n  {line}\n"
    )
    with pytest.raises(ValueError, match=message):
        load_hyperparams("ppo_lag", REVERSE, folder)
    run_dir = tmp_path / "run"
    argv = ["--env", REVERSE, "--algo", "ppo_lag", "--n-trailers", "1", "--timesteps", "64"]
    with pytest.raises(SystemExit) as refused:
        train_command.main([*argv, "--hyperparams", str(folder), "--run-dir", str(run_dir)])
    assert refused.value.code == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert "argument --hyperparams:" in error and "Traceback" not in error
    assert not run_dir.exists()


def test_the_bounds_table_speaks_for_each_algorithm() -> None:
    assert argument_problem("ppo", "batch_size", 1) == "batch_size must be an integer >= 2, got 1"
    assert argument_problem("sac", "batch_size", 1) is None
    assert argument_problem("ppo", "gamma", 1.0) is None
    assert argument_problem("sac", "ent_coef", "auto") is None  # strings are the reader's
    assert argument_problem("ppo", "learning_rate", float("nan")) == (
        "learning_rate must be a finite number, got nan"
    )
