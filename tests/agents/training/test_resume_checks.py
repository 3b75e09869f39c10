"""A resumed run folder is checked whole before anything is written.

``agents.imitate --resume`` and ``agents.train --resume`` read back the run's record,
checkpoint, data set, models and learning curve: a damaged one is a one-line refusal
(exit 2) naming the file, and the folder is left byte for byte as it was. A resumed
training must match its record in every setting that shapes it (the refusal names the
option, with the run's value and the one given), and its budget must grow. The rows a
resumed run keeps in ``evaluations.csv`` stay as they were written.
"""

from __future__ import annotations

import io
import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from agents.artifacts.curves import read_curve
from agents.commands import imitate as imitate_command
from agents.commands import train
from agents.policies.sb3 import load_model
from tests.agents.helpers import rewrite_zip

V0, V1 = "trailer_env/Reverse-v0", "trailer_env/Reverse-v1"

#: A way of damaging a run folder.
Damage = Callable[[Path], object]

#: A tiny imitation run: one convoy labelled by the shipped specialist, one epoch.
IMITATION = [
    "--env",
    V1,
    "--n-trailers",
    "1",
    "--expert",
    "specialists",
    "--episodes",
    "1",
    "--epochs",
    "1",
    "--net-arch",
    "8",
]


def _snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (the lock included, were it left) and its bytes."""
    return {
        str(path.relative_to(folder)): path.read_bytes()
        for path in sorted(folder.rglob("*"))
        if path.is_file()
    }


def _refusal(
    command: Callable[[list[str]], int], argv: list[str], capsys: pytest.CaptureFixture[str]
) -> str:
    """The one-line message of a refused command (exit status 2)."""
    with pytest.raises(SystemExit) as refused:
        command(argv)
    assert refused.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    return err[-1]


@pytest.fixture(scope="module")
def imitation_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    run = tmp_path_factory.mktemp("imitation") / "run"
    assert imitate_command.main([*IMITATION, "--iterations", "1", "--run-dir", str(run)]) == 0
    return run


def _json(name: str, document: object) -> Damage:
    return lambda run: (run / name).write_text(json.dumps(document))


def _edit_json(name: str, **changes: object) -> Damage:
    def damage(run: Path) -> None:
        document = json.loads((run / name).read_text())
        (run / name).write_text(json.dumps({**document, **changes}))

    return damage


def _text(name: str, text: str) -> Damage:
    return lambda run: (run / name).write_text(text)


def _truncate(name: str) -> Damage:
    def damage(run: Path) -> None:
        content = (run / name).read_bytes()
        (run / name).write_bytes(content[: len(content) // 2])

    return damage


def _remove(name: str) -> Damage:
    return lambda run: (run / name).unlink()


def _dataset(**arrays: np.ndarray) -> Damage:
    def damage(run: Path) -> None:
        with np.load(run / "dataset.npz") as saved:
            content = {key: saved[key] for key in saved.files}
        content.update(arrays)
        buffer = io.BytesIO()
        np.savez(buffer, **{key: value for key, value in content.items() if value.size})
        (run / "dataset.npz").write_bytes(buffer.getvalue())

    return damage


def _curve_row(old: str, new: str) -> Damage:
    def damage(run: Path) -> None:
        path = run / "evaluations.csv"
        header, row = path.read_text().splitlines()[:2]
        path.write_text(f"{header}\n{row.replace(old, new, 1)}\n")

    return damage


IMITATION_DAMAGE: dict[str, tuple[Damage, str]] = {
    "checkpoint empty": (_text("checkpoint.json", ""), "checkpoint.json"),
    "checkpoint {}": (_json("checkpoint.json", {}), "checkpoint.json: missing field 'iterations'"),
    "checkpoint a list": (_json("checkpoint.json", []), "checkpoint.json: must be a JSON object"),
    "checkpoint best not numbers": (
        _edit_json("checkpoint.json", best=["high", 0, 0]),
        "checkpoint.json: 'best[0]'",
    ),
    "checkpoint best NaN": (
        _text("checkpoint.json", '{"best": [NaN, 0, 0]}'),
        "checkpoint.json",
    ),
    "checkpoint iterations text": (
        _edit_json("checkpoint.json", iterations="1"),
        "checkpoint.json: 'iterations'",
    ),
    "checkpoint rows negative": (_edit_json("checkpoint.json", rows=-4), "'rows'"),
    "checkpoint wall negative": (_edit_json("checkpoint.json", wall_s=-1.0), "'wall_s'"),
    "checkpoint simulated steps null": (
        _edit_json("checkpoint.json", simulated_steps=None),
        "'simulated_steps'",
    ),
    "checkpoint fit_rng {}": (_edit_json("checkpoint.json", fit_rng={}), "'fit_rng'"),
    "checkpoint fit_rng other generator": (
        _edit_json("checkpoint.json", fit_rng={"bit_generator": "MT19937"}),
        "'fit_rng'",
    ),
    "checkpoint expert_rngs text": (
        _edit_json("checkpoint.json", expert_rngs="none"),
        "'expert_rngs'",
    ),
    "checkpoint expert_rngs damaged": (
        _edit_json("checkpoint.json", expert_rngs=[{"bit_generator": "PCG64"}]),
        "'expert_rngs'[0]",
    ),
    "checkpoint more rows than the data set": (
        _edit_json("checkpoint.json", rows=401),
        "dataset.npz",
    ),
    "checkpoint more iterations than the curve": (
        _edit_json("checkpoint.json", iterations=2),
        "evaluations.csv",
    ),
    "record missing": (_remove("config.json"), "config.json"),
    "record empty": (_text("config.json", ""), "config.json"),
    "record {}": (_json("config.json", {}), "config.json"),
    "record seed text": (_edit_json("config.json", seed="0"), "config.json"),
    "data set missing": (_remove("dataset.npz"), "dataset.npz"),
    "data set truncated": (_truncate("dataset.npz"), "dataset.npz"),
    "data set not a zip": (_text("dataset.npz", "observations"), "dataset.npz"),
    "data set without labels": (_dataset(labels=np.zeros(0)), "dataset.npz"),
    "data set labels flat": (_dataset(labels=np.zeros(400)), "dataset.npz"),
    "data set objects": (
        _dataset(labels=np.array([None] * 400, dtype=object).reshape(400, 1)),
        "dataset.npz",
    ),
    "data set not finite": (
        _dataset(labels=np.full((400, 1), np.nan)),
        "dataset.npz: holds values that are not finite",
    ),
    "data set other observations": (
        _dataset(observations=np.zeros((400, 9), dtype=np.float32)),
        "dataset.npz: observations of 9 numbers",
    ),
    "curve missing": (_remove("evaluations.csv"), "evaluations.csv"),
    "curve empty": (_text("evaluations.csv", ""), "evaluations.csv"),
    "curve not text": (
        lambda run: (run / "evaluations.csv").write_bytes(b"\xff\xfe\x00"),
        "evaluations.csv",
    ),
    "curve value not a number": (_curve_row("0,", "zero,"), "evaluations.csv"),
    "curve other header": (_text("evaluations.csv", "a,b\n1,2\n"), "evaluations.csv"),
    "final model missing": (_remove("final_model.zip"), "final_model.zip: missing"),
    "final model truncated": (_truncate("final_model.zip"), "final_model.zip"),
    "final model weights damaged": (
        lambda run: rewrite_zip(run / "final_model.zip", {"policy.pth": b"not weights"}),
        "final_model.zip",
    ),
    "final statistics missing": (
        _remove("final_model_vecnormalize.json"),
        "final_model_vecnormalize.json: missing",
    ),
    "final statistics {}": (
        _json("final_model_vecnormalize.json", {}),
        "final_model_vecnormalize.json",
    ),
    "best model missing": (_remove("best_model.zip"), "best_model.zip: missing"),
    "best card a list": (_json("best_model.json", []), "best_model.json"),
    "best card selected at text": (
        _edit_json("best_model.json", selected_at_iteration="0"),
        "best_model.json",
    ),
}


@pytest.mark.parametrize("damage", list(IMITATION_DAMAGE))
def test_imitate_refuses_a_damaged_run_folder_and_leaves_it_unchanged(
    imitation_run: Path, tmp_path: Path, damage: str, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    shutil.copytree(imitation_run, run)
    corrupt, named = IMITATION_DAMAGE[damage]
    corrupt(run)
    before = _snapshot(run)
    argv = [*IMITATION, "--iterations", "2", "--run-dir", str(run), "--resume"]
    message = _refusal(imitate_command.main, argv, capsys)
    assert "agents.imitate: error: argument --resume: cannot resume" in message
    assert named in message, message
    assert _snapshot(run) == before


def test_imitate_refuses_another_configuration_naming_old_and_new(
    imitation_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    shutil.copytree(imitation_run, run)
    before = _snapshot(run)
    argv = [*IMITATION, "--iterations", "2", "--run-dir", str(run), "--resume", "--epochs", "3"]
    message = _refusal(imitate_command.main, argv, capsys)
    assert "config.json: its run was configured differently (imitation.epochs = 1, not 3)" in (
        message
    )
    assert _snapshot(run) == before


def test_a_resumed_imitation_keeps_its_curve_rows_as_written(
    imitation_run: Path, tmp_path: Path
) -> None:
    run = tmp_path / "run"
    shutil.copytree(imitation_run, run)
    first = (run / "evaluations.csv").read_text()
    assert first.splitlines()[1].startswith("400,")  # labels counted as an integer
    argv = [*IMITATION, "--iterations", "2", "--run-dir", str(run), "--resume"]
    assert imitate_command.main(argv) == 0
    lines = (run / "evaluations.csv").read_text().splitlines()
    assert "\n".join(lines[:2]) + "\n" == first  # the earlier row byte for byte
    assert len(lines) == 3 and lines[2].startswith("800,")
    record = json.loads((run / "config.json").read_text())
    assert record["resumed_at"] == [1] and record["timesteps"] == 800


# --- agents.train -----------------------------------------------------------------

#: Tiny PPO entries (8 environments, 64-step rollouts, one epoch, an 8-unit network).
TINY_PPO = """\
default: &default
  n_envs: 8
  policy: MlpPolicy
  normalize: "dict(norm_obs=True, norm_reward=False)"
  n_steps: 64
  batch_size: 256
  n_epochs: 1
  policy_kwargs: "dict(net_arch=[8])"
trailer_env/Reverse-v0:
  <<: *default
trailer_env/Reverse-v1:
  <<: *default
"""


def _train_argv(hyperparams: Path, *extra: str, env: str = V1) -> list[str]:
    return [
        "--env",
        env,
        "--algo",
        "ppo",
        "--n-trailers",
        "1",
        "--hyperparams",
        str(hyperparams),
        "--eval-episodes",
        "2",
        "--eval-freq",
        "512",
        "--checkpoint-freq",
        "512",
        "--no-progress",
        "--quiet",
        *extra,
    ]


@pytest.fixture(scope="module")
def training_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A Reverse-v1 run of 1,024 steps with checkpoints at 512 and 1,024, and its file."""
    folder = tmp_path_factory.mktemp("training")
    (folder / "hyperparams").mkdir()
    (folder / "hyperparams" / "ppo.yml").write_text(TINY_PPO)
    argv = _train_argv(folder / "hyperparams", "--timesteps", "1024")
    assert train.main([*argv, "--run-dir", str(folder / "run")]) == 0
    return folder


def _training_copy(training_run: Path, tmp_path: Path) -> tuple[Path, Path]:
    """A copy of the run (and its hyperparameters) in ``tmp_path``."""
    shutil.copytree(training_run, tmp_path / "copy")
    return tmp_path / "copy" / "run", tmp_path / "copy" / "hyperparams"


#: An option given otherwise than the run's: the arguments, the flag the refusal names and
#: the run's and the given value as it shows them.
MISMATCHES = {
    "env": (
        ["--env", V0],
        "argument --env",
        "env_id = trailer_env/Reverse-v1, not trailer_env/Reverse-v0",
    ),
    "seed": (["--seed", "1"], "argument --seed", "seed = 0, not 1"),
    "shaping": (["--shaping", "lqr"], "argument --resume", "no --shaping"),
    "n_envs": (["--n-envs", "4"], "argument --n-envs", "n_envs = 8, not 4"),
    "n_trailers": (
        ["--n-trailers", "2"],
        "argument --n-trailers",
        "env_kwargs.n_trailers = 1, not 2",
    ),
    "randomize": (
        ["--randomize", "mismatch20"],
        "argument --randomize",
        "env_kwargs.randomize = none, not mismatch20",
    ),
    "hyperparams": (
        [],  # the file's entry changed since the run began
        "argument --hyperparams",
        "hyperparams.learning_rate = none, not 0.01",
    ),
}


@pytest.mark.parametrize("option", list(MISMATCHES))
def test_train_resume_refuses_another_setting_naming_old_and_new(
    training_run: Path, tmp_path: Path, option: str, capsys: pytest.CaptureFixture[str]
) -> None:
    run, hyperparams = _training_copy(training_run, tmp_path)
    extra, flag, values = MISMATCHES[option]
    if option == "hyperparams":
        path = hyperparams / "ppo.yml"
        path.write_text(
            path.read_text().replace("n_epochs: 1\n", "n_epochs: 1\n  learning_rate: 0.01\n")
        )
    before = _snapshot(run)
    resume = ["--resume", str(run / "checkpoints" / "ppo_512_steps.zip"), "--timesteps", "2048"]
    message = _refusal(train.main, [*_train_argv(hyperparams, *resume), *extra], capsys)
    assert f"agents.train: error: {flag}: {run.resolve()} was trained with" in message
    assert f"{values}; resume it with the same" in message, message
    assert _snapshot(run) == before


@pytest.mark.parametrize("total", ["512", "1024"])
def test_train_resume_refuses_a_budget_that_does_not_grow(
    training_run: Path, tmp_path: Path, total: str, capsys: pytest.CaptureFixture[str]
) -> None:
    run, hyperparams = _training_copy(training_run, tmp_path)
    before = _snapshot(run)
    resume = ["--resume", str(run / "final_model.zip"), "--timesteps", total]
    message = _refusal(train.main, _train_argv(hyperparams, *resume), capsys)
    assert f"argument --timesteps: {run / 'final_model.zip'} is at 1,024 steps" in message
    assert f"must be above that, got {int(total):,}" in message
    assert _snapshot(run) == before
    assert json.loads((run / "config.json").read_text())["budget"] == 1024


TRAIN_DAMAGE: dict[str, tuple[Damage, str]] = {
    "record empty": (_text("config.json", ""), "config.json"),
    "record {}": (_json("config.json", {}), "config.json lacks 'algo'"),
    "record a list": (_json("config.json", [1]), "config.json is not a JSON object"),
    "record seed text": (_edit_json("config.json", seed="0"), "config.json: 'seed'"),
    "record missing": (_remove("config.json"), "config.json is missing"),
    "curve not text": (
        lambda run: (run / "evaluations.csv").write_bytes(b"\xff\xfe\x00"),
        "evaluations.csv",
    ),
    "curve value not a number": (_curve_row("0,", "zero,"), "evaluations.csv, line 2"),
    "curve other header": (_text("evaluations.csv", "timesteps,safe\n0,1\n"), "evaluations.csv"),
    "curve columns reordered": (
        lambda run: (run / "evaluations.csv").write_text(
            "wall_s,timesteps," + (run / "evaluations.csv").read_text().split(",", 2)[2]
        ),
        "evaluations.csv",
    ),
    "best card a list": (_json("best_model.json", []), "best_model.json"),
    "best card selected at text": (
        _edit_json("best_model.json", selected_at_timesteps="0"),
        "best_model.json",
    ),
    "checkpoint truncated": (_truncate("checkpoints/ppo_512_steps.zip"), "ppo_512_steps.zip"),
    "checkpoint statistics {}": (
        _json("checkpoints/ppo_vecnormalize_512_steps.json", {}),
        "ppo_vecnormalize_512_steps.json",
    ),
}


@pytest.mark.parametrize("damage", list(TRAIN_DAMAGE))
def test_train_resume_refuses_a_damaged_run_folder_and_leaves_it_unchanged(
    training_run: Path, tmp_path: Path, damage: str, capsys: pytest.CaptureFixture[str]
) -> None:
    run, hyperparams = _training_copy(training_run, tmp_path)
    corrupt, named = TRAIN_DAMAGE[damage]
    corrupt(run)
    before = _snapshot(run)
    resume = ["--resume", str(run / "checkpoints" / "ppo_512_steps.zip"), "--timesteps", "2048"]
    message = _refusal(train.main, _train_argv(hyperparams, *resume), capsys)
    assert "agents.train: error: argument --resume: " in message
    assert named in message, message
    assert _snapshot(run) == before
    assert not (run.parent / "runs").exists()  # no fresh folder started instead


def test_a_resumed_training_keeps_its_curve_rows_as_written(
    training_run: Path, tmp_path: Path
) -> None:
    run, hyperparams = _training_copy(training_run, tmp_path)
    lines = (run / "evaluations.csv").read_text().splitlines(keepends=True)
    assert [line.split(",")[0] for line in lines[1:]] == ["0", "512", "1024"]
    resume = ["--resume", str(run / "checkpoints" / "ppo_512_steps.zip"), "--timesteps", "1536"]
    assert train.main(_train_argv(hyperparams, *resume)) == 0
    after = (run / "evaluations.csv").read_text().splitlines(keepends=True)
    assert after[:3] == lines[:3]  # the header and the rows up to 512, byte for byte
    assert [line.split(",")[0] for line in after[1:]] == ["0", "512", "1024", "1536"]
    assert [row["timesteps"] for row in read_curve(run / "evaluations.csv")][-1] == 1536
    assert load_model(run / "final_model.zip").num_timesteps == 1536
    assert json.loads((run / "config.json").read_text())["budget"] == 1536


def test_the_library_checks_a_resumed_folder_before_writing(
    training_run: Path, tmp_path: Path
) -> None:
    from agents.commands.train import build_parser, config_from_args
    from agents.training.sb3 import train as train_library

    run, hyperparams = _training_copy(training_run, tmp_path)
    (run / "evaluations.csv").write_bytes(b"\xff")
    before = _snapshot(run)
    parser = build_parser()

    def config(total: str):  # type: ignore[no-untyped-def]
        args = parser.parse_args(_train_argv(hyperparams, "--timesteps", total))
        return config_from_args(parser, args, [])

    resume = run / "final_model.zip"
    with pytest.raises(ValueError, match=r"evaluations\.csv is not UTF-8"):
        train_library(config("2048"), run, resume=resume, progress_bar=False, verbose=0)
    with pytest.raises(ValueError, match="is at 1024 steps; the run's total budget must be"):
        train_library(config("1000"), run, resume=resume, progress_bar=False, verbose=0)
    assert _snapshot(run) == before


def test_train_resume_refuses_an_imitation_run(
    imitation_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    shutil.copytree(imitation_run, run)
    before = _snapshot(run)
    argv = ["--env", V1, "--algo", "ppo", "--n-trailers", "1", "--timesteps", "100000"]
    message = _refusal(train.main, [*argv, "--resume", str(run / "final_model.zip")], capsys)
    assert f"argument --resume: {run.resolve()} holds a dagger run" in message
    assert "--init-from" in message
    assert _snapshot(run) == before


def test_overwrite_clears_what_a_resume_reads_back(tmp_path: Path) -> None:
    from agents.artifacts.run_folder import clear_run

    names = ["checkpoint.json", "dataset.npz", "final_model.zip", "final_model.json"]
    names += ["final_model_vecnormalize.json", "config.json", "evaluations.csv", "notes.txt"]
    for name in names:
        (tmp_path / name).write_text("earlier run")
    (tmp_path / "logs").mkdir()
    clear_run(tmp_path, everything=False)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["logs", "notes.txt"]


def test_keep_rows_keeps_the_lines_as_written(tmp_path: Path) -> None:
    from agents.artifacts.curves import keep_rows

    path = tmp_path / "evaluations.csv"
    text = "timesteps,safe_rate\n0,0.5\n800,0.75\n1600,1\n2400,0."
    path.write_text(text)
    kept = keep_rows(path, lambda row: row["timesteps"] <= 800)
    assert kept == [{"timesteps": 0.0, "safe_rate": 0.5}, {"timesteps": 800.0, "safe_rate": 0.75}]
    assert path.read_text() == "timesteps,safe_rate\n0,0.5\n800,0.75\n"
    untouched = path.stat().st_mtime_ns
    assert len(keep_rows(path, lambda row: True)) == 2
    assert path.stat().st_mtime_ns == untouched  # nothing dropped: not rewritten
    assert keep_rows(tmp_path / "absent.csv", lambda row: True) == []


def test_a_run_or_resume_that_fails_before_new_work_changes_nothing(
    imitation_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import agents.training.imitate as imitation

    def labelling_fails(*args: object, **kwargs: object) -> None:
        raise RuntimeError("the expert failed")

    monkeypatch.setattr(imitation, "collect", labelling_fails)
    run = tmp_path / "run"
    shutil.copytree(imitation_run, run)
    before = _snapshot(run)
    with pytest.raises(RuntimeError, match="the expert failed"):
        imitate_command.main([*IMITATION, "--iterations", "2", "--run-dir", str(run), "--resume"])
    assert _snapshot(run) == before  # the record, the curve and the lock as they were
    fresh = tmp_path / "fresh"
    with pytest.raises(RuntimeError, match="the expert failed"):
        imitate_command.main([*IMITATION, "--iterations", "1", "--run-dir", str(fresh)])
    assert not fresh.exists()  # no record left behind to refuse the next start


def test_a_record_with_sb3s_default_use_sde_matches_the_files_that_lack_it() -> None:
    """SB3's off-policy algorithms wrote ``use_sde: False`` into the policy_kwargs they were
    given: a record holding it still matches a continuation built from the files."""
    from agents.artifacts.cards import ModelCard
    from agents.artifacts.run_folder import record_differences

    saved = ModelCard(hyperparams={"policy_kwargs": {"net_arch": [64, 64], "use_sde": False}})
    wanted = ModelCard(hyperparams={"policy_kwargs": {"net_arch": [64, 64]}})
    assert record_differences(saved, wanted) == []
    wider = ModelCard(hyperparams={"policy_kwargs": {"net_arch": [256, 256]}})
    assert record_differences(saved, wider) == [
        ("hyperparams.policy_kwargs", {"net_arch": [64, 64]}, {"net_arch": [256, 256]})
    ]
