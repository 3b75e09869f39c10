"""Issue 21: nothing silent, nothing destroyed, nothing unbounded.

Every reproducer asserts the exit status (2), the one-line message naming the argument
or file, and that nothing was written (the folder's files are the same before and
after the refusal).
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from agents.artifacts import files
from agents.artifacts.certificates import (
    read_certificate,
    write_certificate,
)
from agents.artifacts.curves import CURVE_COLUMNS, append_rows, read_curve
from agents.artifacts.run_folder import CONFIG_FILE
from agents.commands import certify, evaluate, imitate, report, train
from tests.agents.helpers import fake_certified, model_copy, rewrite_zip

REVERSE = "trailer_env/Reverse-v0"
ROOT = Path(__file__).resolve().parents[3]


def snapshot(folder: Path) -> dict[str, str]:
    """Every entry under ``folder`` (links included, not followed) with its content's hash."""
    if not folder.exists():
        return {}
    found = {}
    for path in sorted(folder.rglob("*")):
        key = str(path.relative_to(folder))
        if path.is_symlink():
            found[key] = "-> " + os.readlink(path)
        elif path.is_file():
            found[key] = hashlib.sha256(path.read_bytes()).hexdigest()
        else:
            found[key] = "dir"
    return found


def refused(
    command: Callable[[list[str]], int],
    argv: list[str],
    message: str,
    folder: Path,
    capsys: pytest.CaptureFixture[str],
) -> str:
    """Run ``command`` and check: exit 2, ``message`` in the one-line error, ``folder``
    unchanged. Returns the error line."""
    before = snapshot(folder)
    with pytest.raises(SystemExit) as raised:
        command(argv)
    err = capsys.readouterr().err
    line = err.strip().splitlines()[-1]
    assert raised.value.code == 2, err
    assert message in line, line
    assert snapshot(folder) == before, "a refusal changed files"
    return line


# ---------------------------------------------------------------- evaluate: bad model files


def _evaluate_argv(model: Path, out: Path, *extra: str) -> list[str]:
    return [
        "--env",
        REVERSE,
        "--n-trailers",
        "2",
        "--policy",
        str(model),
        "--episodes",
        "2",
        "--no-plots",
        "--out",
        str(out),
        *extra,
    ]


def _edit_json(path: Path, edit: Callable[[dict[str, Any]], None]) -> None:
    document = json.loads(path.read_text())
    edit(document)
    path.write_text(json.dumps(document))


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda card: card.update(algo=[]), "'algo' must be str"),
        (lambda card: card.update(env_kwargs=[]), "'env_kwargs' must be an object, got a list"),
        (lambda card: card.update(timesteps="abc"), "'timesteps' must be int"),
        (
            lambda card: card.update(wall_time_s=float("nan")),
            "'wall_time_s' must be a finite number, got nan",
        ),
    ],
)
def test_evaluate_refuses_a_bad_card(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], edit: Any, message: str
) -> None:
    model = model_copy(tmp_path / "m")
    _edit_json(model.with_suffix(".json"), edit)
    line = refused(
        evaluate.main, _evaluate_argv(model, tmp_path / "out"), message, tmp_path, capsys
    )
    assert "argument --policy" in line and "ppo_reverse_n2.json" in line


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda stats: stats.pop("clip_obs"), "missing field 'clip_obs'"),
        (lambda stats: stats["obs_rms"].update(mean={}), "obs_rms: 'mean' must be a list"),
        (lambda stats: stats.update(gamma="x"), "'gamma' must be float, got str 'x'"),
        (
            lambda stats: stats["obs_rms"]["var"].append(1.0),
            "'mean' and 'var' must be of one length",
        ),
    ],
)
def test_evaluate_refuses_bad_statistics(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], edit: Any, message: str
) -> None:
    model = model_copy(tmp_path / "m")
    _edit_json(model.with_name("ppo_reverse_n2_vecnormalize.json"), edit)
    refused(evaluate.main, _evaluate_argv(model, tmp_path / "out"), message, tmp_path, capsys)


def _network(model: Path, net_arch: list[int]) -> None:
    with zipfile.ZipFile(model) as archive:
        data = json.loads(archive.read("data"))
    data["policy_kwargs"] = {"net_arch": net_arch}
    rewrite_zip(model, {"data": json.dumps(data).encode()})


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (
            lambda model: model.with_suffix(".json").write_text("[" * 200_000 + "]" * 200_000),
            "nested 200000 deep, over the limit of 64",
        ),
        (
            lambda model: model.with_name("ppo_reverse_n2_vecnormalize.json").unlink(),
            "statistics ppo_reverse_n2_vecnormalize.json are missing",
        ),
        # 20 MiB of spaces deflate to about 20 kB: a zip bomb, refused before inflating.
        (
            lambda model: rewrite_zip(model, {"data": b" " * (20 * 2**20)}, zipfile.ZIP_DEFLATED),
            "member 'data' inflates to 20971520 bytes",
        ),
        (lambda model: _network(model, [40000, 40000]), "parameters, over the limit of 10,000,000"),
    ],
)
def test_evaluate_refuses_a_damaged_model(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], damage: Any, message: str
) -> None:
    model = model_copy(tmp_path / "m")
    damage(model)
    assert model.stat().st_size < 2**20
    refused(evaluate.main, _evaluate_argv(model, tmp_path / "out"), message, tmp_path, capsys)


def test_evaluate_refuses_a_garbage_curve(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = model_copy(tmp_path / "m")
    model.with_suffix(".csv").write_bytes(b"\x00garbage,\xff\n1,2\n")
    refused(evaluate.main, _evaluate_argv(model, tmp_path / "out"), "curve", tmp_path, capsys)
    model.with_suffix(".csv").write_text(",".join(CURVE_COLUMNS) + "\nabc,1\n1,2,3,4,5,6,7,8\n")
    refused(evaluate.main, _evaluate_argv(model, tmp_path / "out"), "line 2", tmp_path, capsys)


# ---------------------------------------------------------------- evaluate: bounds and outputs


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--seed", str(2**64)], "argument --seed: must be <= 4294967295"),
        (["--seed", str(2**32 - 1)], "argument --seed: seed 4294967295 would need seeds up to"),
        (["--episodes", "1e7"], "argument --episodes: must be <= 100,000"),
        (["--episodes", "1e999"], "argument --episodes: expected a positive integer"),
    ],
)
def test_evaluate_bounds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], message: str
) -> None:
    argv = [
        "--policy",
        "zero",
        "--no-plots",
        "--out",
        str(tmp_path / "out"),
        "--episodes",
        "2",
        *extra,
    ]
    refused(evaluate.main, argv, message, tmp_path, capsys)


def test_episodes_bound_is_in_the_help(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        evaluate.main(["--help"])
    assert "at most 100,000" in capsys.readouterr().out


def test_evaluate_checks_its_outputs_first(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    a_file = tmp_path / "FILE"
    a_file.write_text("x")
    base = ["--policy", "zero", "--episodes", "2", "--no-plots"]
    refused(
        evaluate.main,
        [*base, "--out", str(a_file / "sub")],
        f"argument --out: cannot create {a_file / 'sub'}: {a_file} is not a folder",
        tmp_path,
        capsys,
    )
    out = tmp_path / "out"
    refused(
        evaluate.main,
        [*base, "--out", str(out), "--video", str(a_file / "v.mp4")],
        "argument --video: cannot create",
        tmp_path,
        capsys,
    )
    dangling = tmp_path / "v.gif"
    dangling.symlink_to(tmp_path / "elsewhere.gif")
    refused(
        evaluate.main,
        [*base, "--out", str(out), "--video", str(dangling)],
        "argument --video: ",
        tmp_path,
        capsys,
    )
    assert not (tmp_path / "elsewhere.gif").exists()
    out.mkdir()
    (out / "results.json").symlink_to(tmp_path / "target.json")
    refused(
        evaluate.main,
        [*base, "--out", str(out)],
        "results.json is a symbolic link",
        tmp_path,
        capsys,
    )
    (out / "results.json").unlink()
    locked = tmp_path / "ro"
    locked.mkdir()
    real_access = os.access
    monkeypatch.setattr(
        files.os, "access", lambda path, mode: Path(path) != locked and real_access(path, mode)
    )
    refused(
        evaluate.main,
        [*base, "--out", str(locked / "out")],
        f"argument --out: cannot create {locked / 'out'}: {locked} is not writable",
        tmp_path,
        capsys,
    )


def test_evaluate_keeps_an_earlier_evaluation_unless_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Issue 27 item 5: results.json of an existing --out was replaced without --overwrite.
    out = tmp_path / "out"
    base = ["--policy", "zero", "--episodes", "2", "--no-plots", "--out", str(out)]
    assert evaluate.main(base) == 0
    capsys.readouterr()
    refused(
        evaluate.main,
        base,
        f"argument --out: {out} holds results.json, results.md of an earlier evaluation; "
        "pass --overwrite to replace them",
        tmp_path,
        capsys,
    )
    (out / "results.json").unlink()
    (out / "results.md").unlink()
    (out / "curves.png").write_bytes(b"an earlier picture")
    assert evaluate.main(base) == 0  # --no-plots writes no picture: nothing to replace
    capsys.readouterr()
    refused(
        evaluate.main,
        [*base, "--episodes", "3"],
        "holds results.json, results.md",
        tmp_path,
        capsys,
    )
    refused(
        evaluate.main,
        [arg for arg in base if arg != "--no-plots"],
        "holds results.json, results.md, curves.png",
        tmp_path,
        capsys,
    )
    assert evaluate.main([*base, "--episodes", "3", "--overwrite"]) == 0
    assert json.loads((out / "results.json").read_text())["episodes"] == 3
    assert (out / "curves.png").read_bytes() == b"an earlier picture"


def test_a_deeply_nested_set_value_is_a_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    deep = "[" * 100_000 + "]" * 100_000  # json.loads raised RecursionError
    argv = [
        "--policy",
        "zero",
        "--episodes",
        "2",
        "--no-plots",
        "--out",
        str(tmp_path / "out"),
        "--set",
        f"fidelity={deep}",
    ]
    refused(
        evaluate.main,
        argv,
        "argument --set: fidelity: the value is nested 100000 deep, over the limit of 64",
        tmp_path,
        capsys,
    )
    argv[-1] = "fidelity=" + "[" * 65 + "]" * 65
    refused(evaluate.main, argv, "nested 65 deep", tmp_path, capsys)


@pytest.mark.parametrize(
    ("code", "message"),
    [
        ("raise RuntimeError('boom')", "raised RuntimeError: boom"),
        ("import sys\nsys.exit(0)", "raised SystemExit: 0"),
        ("raise SystemExit('bye')", "raised SystemExit: bye"),
        ("1 / 0", "raised ZeroDivisionError: division by zero"),
    ],
)
def test_a_policy_module_whose_import_fails_is_a_one_line_error(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    code: str,
    message: str,
) -> None:
    modules = tmp_path / "modules"
    modules.mkdir()
    (modules / "failing_policy_27.py").write_text(code + "\ndef act(obs):\n    return obs\n")
    monkeypatch.syspath_prepend(str(modules))
    argv = [
        "--policy",
        "failing_policy_27:act",
        "--episodes",
        "2",
        "--no-plots",
        "--out",
        str(tmp_path / "out"),
    ]
    line = refused(evaluate.main, argv, message, tmp_path, capsys)
    assert line.endswith(
        f"error: argument --policy: policy 'failing_policy_27:act': importing "
        f"'failing_policy_27' {message}"
    )
    assert "failing_policy_27" not in sys.modules


# ---------------------------------------------------------------- train


def _hyperparams(folder: Path, **entry: Any) -> Path:
    import yaml

    folder.mkdir(parents=True, exist_ok=True)
    base = {
        "n_envs": 2,
        "n_timesteps": 64,
        "policy": "MlpPolicy",
        "n_steps": 16,
        "batch_size": 16,
        "n_epochs": 1,
    }
    (folder / "ppo.yml").write_text(yaml.safe_dump({REVERSE: {**base, **entry}}))
    return folder


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--torch-threads", "1000000"], "argument --torch-threads: must be <="),
        (["--eval-episodes", "1e8"], "argument --eval-episodes: must be <= 100,000"),
        (["--n-envs", "100000000"], "argument --n-envs: must be <= 65,536"),
        (["--timesteps", "1e30"], "argument --timesteps: must be <= 2,147,483,648"),
        (["--seed", str(2**32 - 10)], "would need seeds up to"),
    ],
)
def test_train_bounds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], message: str
) -> None:
    argv = ["--env", REVERSE, "--algo", "ppo", "--run-dir", str(tmp_path / "run"), *extra]
    refused(train.main, argv, message, tmp_path, capsys)
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ({"batch_size": "abc"}, "batch_size must be an integer"),
        (
            {"policy": "CnnPolicy"},
            "policy must be one of ('MlpPolicy', 'MultiInputPolicy'), got 'CnnPolicy'",
        ),
        ({"surprise": 1}, "unknown key 'surprise'"),
        ({"policy_kwargs": "dict(net_arch=[40000, 40000])"}, "over the limit of 10,000,000"),
        ({"n_envs": 100_000_000}, "n_envs must be an integer in 1..65536"),
        ({"gamma": ".99x"}, "gamma must be a finite number"),
        ({"normalize": "dict(norm_obs=True, bogus=1)"}, "normalize has no setting 'bogus'"),
        ({"n_steps": 1_000_000, "n_envs": 64}, "steps per rollout"),
    ],
)
def test_train_refuses_bad_hyperparameters(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], entry: dict[str, Any], message: str
) -> None:
    folder = _hyperparams(tmp_path / "hp", **entry)
    argv = [
        "--env",
        REVERSE,
        "--algo",
        "ppo",
        "--hyperparams",
        str(folder),
        "--run-dir",
        str(tmp_path / "run"),
    ]
    line = refused(train.main, argv, message, tmp_path, capsys)
    assert "argument --hyperparams" in line


def test_train_checks_export_and_run_folder_first(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a_file = tmp_path / "FILE"
    a_file.write_text("x")
    hp = _hyperparams(tmp_path / "hp")
    base = ["--env", REVERSE, "--algo", "ppo", "--hyperparams", str(hp), "--timesteps", "64"]
    refused(
        train.main,
        [*base, "--run-dir", str(tmp_path / "run"), "--export", str(a_file / "m.zip")],
        "argument --export: cannot create",
        tmp_path,
        capsys,
    )
    assert not (tmp_path / "run").exists()
    # A symlinked checkpoints/ survives no --overwrite and receives nothing.
    run = tmp_path / "run"
    run.mkdir()
    (run / CONFIG_FILE).write_text("{}")
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "keep.txt").write_text("mine")
    (run / "checkpoints").symlink_to(outside)
    refused(
        train.main,
        [*base, "--run-dir", str(run), "--overwrite"],
        "checkpoints is a symbolic link",
        tmp_path,
        capsys,
    )
    (run / "checkpoints").unlink()
    # A config.json linked elsewhere is not written through.
    (run / CONFIG_FILE).unlink()
    (run / CONFIG_FILE).symlink_to(outside / "keep.txt")
    refused(
        train.main,
        [*base, "--run-dir", str(run), "--overwrite"],
        "config.json is a symbolic link",
        tmp_path,
        capsys,
    )
    assert (outside / "keep.txt").read_text() == "mine"


def test_a_locked_run_folder_refuses_a_second_writer(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    run.mkdir()
    (run / ".lock").write_text("1\n")  # pid 1 is alive
    argv = [
        "--env",
        REVERSE,
        "--algo",
        "ppo",
        "--run-dir",
        str(run),
        "--timesteps",
        "64",
        "--hyperparams",
        str(_hyperparams(tmp_path / "hp")),
    ]
    refused(train.main, argv, f"argument --run-dir: {run} is in use by process 1", tmp_path, capsys)


def test_a_stale_lock_is_reclaimed_and_a_live_one_refuses(tmp_path: Path) -> None:
    finished = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    )
    (tmp_path / ".lock").write_text(finished.stdout)  # its process is gone
    with files.RunLock(tmp_path):
        assert (tmp_path / ".lock").read_text().strip() == str(os.getpid())
    assert not (tmp_path / ".lock").exists()
    (tmp_path / ".lock").write_text("1\n")
    with pytest.raises(files.FolderLockedError, match="in use by process 1"):
        files.RunLock(tmp_path).acquire()
    assert (tmp_path / ".lock").read_text() == "1\n"


def test_rllib_address_and_runners_are_checked_before_ray(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = [
        "--backend",
        "rllib",
        "--env",
        REVERSE,
        "--algo",
        "ppo",
        "--run-dir",
        str(tmp_path / "run"),
    ]
    refused(train.main, [*base, "--address", "garbage"], "is not auto, HOST:PORT", tmp_path, capsys)
    refused(
        train.main, [*base, "--address", "garbage.invalid:1234"], "cannot reach", tmp_path, capsys
    )
    refused(
        train.main,
        [*base, "--num-env-runners", "1000"],
        f"this machine has {os.cpu_count()} CPUs",
        tmp_path,
        capsys,
    )


# ---------------------------------------------------------------- certify, report, imitate


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--n-trailers", "300"], "argument --n-trailers"),
        (["--seeds", "-5"], "argument --seeds: expected N or a range LOW-HIGH"),
        (["--seeds", "4294967296"], "argument --seeds: must be in 0..4,294,967,295"),
        (["--seeds", "1000-1099999999"], "argument --seeds: more than 10,000 integers"),
        (["--seeds", "1,1"], "an integer appears twice"),
        (["--seeds", "abc"], "expected N or a range LOW-HIGH such as 1-3, got 'abc'"),
        (["--samples", "100000000"], "argument --samples: must be <= 1,024"),
    ],
)
def test_certify_bounds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], message: str
) -> None:
    argv = ["--env", "trailer_env/Reverse-v1", "--out", str(tmp_path / "cert"), *extra]
    refused(certify.main, argv, message, tmp_path, capsys)


def test_certify_overwrite_replaces_only_its_own_files(tmp_path: Path) -> None:
    out = tmp_path / "cert"
    write_certificate(fake_certified([1, 2]), out, overwrite=False)
    (out / "notes.txt").write_text("mine")
    (out / "actions" / "mine.npy").write_text("mine")
    write_certificate(fake_certified([3]), out, overwrite=True)
    assert (out / "notes.txt").read_text() == "mine"
    assert (out / "actions" / "mine.npy").read_text() == "mine"
    assert sorted(path.name for path in (out / "actions").iterdir()) == ["mine.npy", "seed_3.npy"]
    assert read_certificate(out / "certificate.json").seeds == (3, 3)
    (out / "certificate.md").unlink()
    (out / "certificate.md").symlink_to(tmp_path / "elsewhere.md")
    with pytest.raises(files.UnsafeFileError, match=r"certificate\.md is a symbolic link"):
        write_certificate(fake_certified([3]), out, overwrite=True)
    assert not (tmp_path / "elsewhere.md").exists()


def test_certify_out_dot_keeps_the_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "precious.txt").write_text("mine")
    monkeypatch.setattr(certify, "certify", lambda *args, **kwargs: fake_certified([1000]))
    assert certify.main(["--seeds", "1000", "--out", ".", "--overwrite"]) == 0
    assert (tmp_path / "precious.txt").read_text() == "mine"
    assert (tmp_path / "certificate.json").is_file()


def test_report_refuses_a_file_as_out(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a_file = tmp_path / "FILE"
    a_file.write_text("x")
    refused(
        report.main,
        ["--out", str(a_file), "--docs", str(tmp_path / "docs")],
        f"argument --out: {a_file} exists and is not a folder",
        tmp_path,
        capsys,
    )


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--episodes", "1e8"], "argument --episodes: must be <= 4,096"),
        (["--net-arch", "40000", "40000"], "argument --net-arch: net_arch [40000, 40000] has"),
        (["--planner-samples", "100000"], "argument --planner-samples: must be <= 1,024"),
        (["--seed", "4000000"], "training episodes would need seeds up to"),
    ],
)
def test_imitate_bounds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], message: str
) -> None:
    refused(imitate.main, ["--run-dir", str(tmp_path / "run"), *extra], message, tmp_path, capsys)


# ---------------------------------------------------------------- files


def test_atomic_writes_refuse_links_and_leave_no_temporary_files(tmp_path: Path) -> None:
    target = tmp_path / "a.json"
    files.write_json(target, {"b": 1, "a": 2})
    assert target.read_text() == '{\n  "a": 2,\n  "b": 1\n}\n'
    link = tmp_path / "link.json"
    link.symlink_to(tmp_path / "nowhere.json")
    with pytest.raises(files.UnsafeFileError, match="symbolic link"):
        files.atomic_write_text(link, "x")
    assert not (tmp_path / "nowhere.json").exists()
    assert sorted(path.name for path in tmp_path.iterdir()) == ["a.json", "link.json"]


@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_written_files_honour_the_umask(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], umask: int
) -> None:
    # Issue 27 item 4: every file was 0600 (mkstemp's mode outlived the rename).
    import matplotlib.pyplot as plt

    previous = os.umask(umask)
    try:
        files.write_json(tmp_path / "a.json", {"a": 1})
        figure = plt.figure()
        with files.replacing(tmp_path / "a.png") as temporary:  # as the pictures are written
            figure.savefig(temporary)
        plt.close(figure)
        out = tmp_path / "out"
        argv = ["--policy", "zero", "--episodes", "2", "--no-plots", "--out", str(out)]
        assert evaluate.main(argv) == 0
    finally:
        os.umask(previous)
    capsys.readouterr()
    written = [tmp_path / "a.json", tmp_path / "a.png", out / "results.json", out / "results.md"]
    assert [oct(path.stat().st_mode & 0o777) for path in written] == [oct(0o666 & ~umask)] * 4
    assert files.file_mode() == 0o666 & ~os.umask(previous)  # reading it changed nothing


def test_a_cut_last_row_is_tolerated_and_cut_on_append(tmp_path: Path) -> None:
    curve = tmp_path / "evaluations.csv"
    row = dict.fromkeys(CURVE_COLUMNS, 1.0)
    append_rows(curve, [row, {**row, "timesteps": 2.0}])
    content = curve.read_text()
    curve.write_text(content + "3,4.5,1")  # a run killed while appending
    assert [r["timesteps"] for r in read_curve(curve, CURVE_COLUMNS)] == [1.0, 2.0]
    append_rows(curve, [{**row, "timesteps": 4.0}])
    assert [r["timesteps"] for r in read_curve(curve, CURVE_COLUMNS)] == [1.0, 2.0, 4.0]
    curve.write_text(content.replace("1.0", "x", 1))
    with pytest.raises(ValueError, match="line 2"):
        read_curve(curve)


def test_python_m_agents_screen_is_no_command() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "agents.screen", "--help"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode != 0 and "No module named agents.screen" in result.stderr


def test_resume_does_not_write_through_a_linked_curve(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from tests.agents.helpers import tiny_model

    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / CONFIG_FILE).write_text("{}")
    checkpoint = tiny_model(run / "checkpoints" / "ppo_64_steps.zip")
    outside = tmp_path / "outside.csv"
    outside.write_text("timesteps\n")
    (run / "evaluations.csv").symlink_to(outside)
    argv = [
        "--env",
        REVERSE,
        "--algo",
        "ppo",
        "--n-trailers",
        "1",
        "--resume",
        str(checkpoint),
        "--timesteps",
        "128",
        "--hyperparams",
        str(_hyperparams(tmp_path / "hp")),
    ]
    refused(train.main, argv, "evaluations.csv is a symbolic link", tmp_path, capsys)
    assert outside.read_text() == "timesteps\n"


def test_main_and_convert_stats_check_first(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from agents.commands import convert_stats, main

    refused(
        main.main,
        ["--out", str(tmp_path / "out"), "--retrain", "--train-episodes", "1e6"],
        "argument --train-episodes",
        tmp_path,
        capsys,
    )
    pickled = tmp_path / "old.pkl"
    pickled.write_bytes(b"not read")
    link = tmp_path / "new.json"
    link.symlink_to(tmp_path / "elsewhere.json")
    refused(
        convert_stats.main,
        ["--trust-pickle", str(pickled), str(link)],
        "argument destination: ",
        tmp_path,
        capsys,
    )
