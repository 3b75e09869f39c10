"""Exit codes and messages of the commands, and the evaluation's determinism under a seed."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from stable_baselines3 import PPO

from agents.artifacts.run_folder import run_dir_of_checkpoint
from agents.artifacts.shipped import MODELS_DIR, resolve_model
from agents.commands import evaluate, main, train
from agents.envs import env_settings, make_sb3_env
from agents.evaluation.metrics import rollout
from agents.policies.baselines import make_baseline
from tests.agents.helpers import model_copy, rewrite_zip, tiny_model

REVERSE = "trailer_env/Reverse-v0"
ROOT = Path(__file__).resolve().parents[3]


def _exit(command, argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:  # type: ignore[no-untyped-def]
    with pytest.raises(SystemExit) as raised:
        command(argv)
    return int(raised.value.code), capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--algo", "ppo"], "the following arguments are required: --env"),
        (
            ["--env", "CartPole-v1", "--algo", "ppo"],
            "argument --env: invalid choice: 'CartPole-v1'",
        ),
        (["--env", REVERSE, "--algo", "dqn"], "argument --algo: invalid choice: 'dqn'"),
        (["--env", REVERSE, "--algo", "ppo", "--timesteps", "-5"], "argument --timesteps"),
        (["--env", REVERSE, "--algo", "ppo", "--timesteps", "1.5"], "argument --timesteps"),
        (["--env", REVERSE, "--algo", "ppo", "--n-trailers", "two"], "argument --n-trailers"),
        (["--env", REVERSE, "--algo", "ppo", "--resume", "absent.zip"], "no checkpoint file"),
        (["--env", REVERSE, "--algo", "ppo", "--hyperparams", "/nonexistent"], "no hyperparameter"),
    ],
)
def test_train_rejects_bad_arguments(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code, err = _exit(train.main, argv, capsys)
    assert code == 2
    assert message in err


def test_train_refuses_a_resume_of_another_algorithm(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    saved = tmp_path / "ppo_model.zip"
    PPO("MlpPolicy", make_sb3_env(REVERSE, 2, {"n_trailers": 1}), device="cpu").save(saved)
    argv = ["--env", REVERSE, "--algo", "sac", "--n-trailers", "1", "--resume", str(saved)]
    code, err = _exit(train.main, argv, capsys)
    assert code == 2 and "was saved by ppo, not sac" in err


def test_train_refuses_to_overwrite_a_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "evaluations.csv").write_text("timesteps\n")
    argv = ["--env", REVERSE, "--algo", "ppo", "--run-dir", str(tmp_path)]
    code, err = _exit(train.main, argv, capsys)
    assert code == 2 and "already holds a run" in err and "--overwrite" in err


def test_train_rejects_bad_environment_settings(capsys: pytest.CaptureFixture[str]) -> None:
    code, err = _exit(train.main, ["--env", REVERSE, "--algo", "ppo", "--n-trailers", "-1"], capsys)
    assert code == 2 and "argument --n-trailers" in err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--env", "trailer_env/Park-v0"], "argument --env: invalid choice"),
        (["--policy", "bogus"], "argument --policy: unknown policy 'bogus'"),
        (["--policy", "missing/model.zip"], "argument --policy: no model file missing/model.zip"),
        (["--episodes", "0"], "argument --episodes: must be >= 1"),
        (["--n-trailers", "-2"], "argument --n-trailers: must be >= 0"),
        (["--policy", "heading-p"], "heading-p baseline is for trailer_env/Heading-v0"),
    ],
)
def test_evaluate_rejects_bad_arguments(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code, err = _exit(evaluate.main, [*argv, "--no-plots", "--out", "/tmp/unused"], capsys)
    assert code == 2
    assert message in err


def test_main_rejects_bad_arguments(capsys: pytest.CaptureFixture[str]) -> None:
    code, err = _exit(main.main, ["--episodes", "0"], capsys)
    assert code == 2 and "argument --episodes" in err


def test_evaluation_is_deterministic_under_a_seed(tmp_path: Path) -> None:
    model = tiny_model(tmp_path / "tiny.zip", n=2)
    outputs = []
    for name in ("a", "b"):
        argv = ["--policy", "zero", "random", "lqr", str(model), "--episodes", "20", "--seed", "5"]
        assert evaluate.main([*argv, "--no-plots", "--out", str(tmp_path / name)]) == 0
        outputs.append((tmp_path / name / "results.json").read_bytes())
    assert outputs[0] == outputs[1]
    document = json.loads(outputs[0])
    names = [policy["name"] for policy in document["policies"]]
    assert document["seeds"] == [5, 24] and names == ["zero", "random", "lqr", "tiny"]
    assert document["policies"][0]["jackknife_rate"] == 1.0
    table = (tmp_path / "a" / "results.md").read_text().splitlines()
    assert len([line for line in table if line.startswith("| ")]) == 1 + 4  # header + rows


def test_commands_exit_nonzero_in_a_fresh_process() -> None:
    """The real entry points: argparse's exit status 2 and a message naming the argument."""
    done = subprocess.run(
        [sys.executable, "-m", "agents.train", "--env", REVERSE, "--algo", "a2c"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 2 and "argument --algo" in done.stderr


@pytest.mark.filterwarnings("ignore:Detected pickle protocol:UserWarning")  # the garbage
def test_evaluate_errors_name_their_argument(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    garbage = model_copy(tmp_path / "garbage")
    rewrite_zip(garbage, {"policy.pth": b"\x80\x04garbage" * 50})
    cases = [
        (["--seed", "-1"], "argument --seed: expected an integer >= 0, got '-1'"),
        (["--out", str(a_file)], f"argument --out: {a_file} exists and is not a folder"),
        (
            ["--env", "trailer_env/Reverse-v0", "--policy", str(garbage)],
            "argument --policy: cannot load model",
        ),
        (
            # Coast-v0 observations have Reverse-v0's shape: only the card tells them apart.
            ["--env", "trailer_env/Coast-v0", "--policy", "ppo_reverse_n2"],
            "was trained on trailer_env/Reverse-v0 with n_trailers = 2, not "
            "trailer_env/Coast-v0 with n_trailers = 2; pass --force",
        ),
        (
            ["--env", "trailer_env/Reverse-v0", "--n-trailers", "1", "--policy", "ppo_reverse_n2"],
            "with n_trailers = 2, not",
        ),
        (["--video", str(tmp_path / "v.avi")], "argument --video: must end in .mp4 or .gif"),
    ]
    for argv, message in cases:
        out = [] if "--out" in argv else ["--out", str(tmp_path / "out")]
        code, err = _exit(evaluate.main, [*argv, "--no-plots", "--episodes", "2", *out], capsys)
        assert code == 2 and message in err, (argv, err)
        assert "Traceback" not in err


def test_evaluate_forced_onto_another_scene_runs(tmp_path: Path) -> None:
    argv = ["--env", "trailer_env/Coast-v0", "--policy", "ppo_reverse_n2", "--force"]
    assert evaluate.main([*argv, "--episodes", "2", "--no-plots", "--out", str(tmp_path)]) == 0
    document = json.loads((tmp_path / "results.json").read_text())
    assert [policy["name"] for policy in document["policies"]] == ["ppo_reverse_n2"]


def test_shipped_models_are_named_by_stem_from_any_folder(tmp_path: Path) -> None:
    """A fresh process in an unrelated folder: the stem resolves through the package."""
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "agents.evaluate",
            "--env",
            "trailer_env/Reverse-v0",
            "--policy",
            "ppo_reverse_n2",
            "lqr",
            "--episodes",
            "3",
            "--no-plots",
            "--out",
            "out",
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    assert done.returncode == 0, done.stderr
    document = json.loads((tmp_path / "out" / "results.json").read_text())
    names = [policy["name"] for policy in document["policies"]]
    assert names == ["ppo_reverse_n2", "lqr"] and document["policies"][0]["kind"] == "model"
    assert resolve_model("ppo_reverse_n2") == str(MODELS_DIR / "ppo_reverse_n2.zip")
    assert resolve_model("lqr") == "lqr" and resolve_model("absent_model") == "absent_model"


@pytest.mark.parametrize(("suffix", "steps"), [(".gif", None), (".mp4", 30)])
def test_evaluate_writes_a_video_of_one_episode(
    tmp_path: Path, suffix: str, steps: int | None
) -> None:
    import imageio.v2 as imageio
    from PIL import Image

    video = tmp_path / f"episode{suffix}"
    cut = [] if steps is None else ["--video-steps", str(steps)]
    argv = [
        "--env",
        REVERSE,
        "--policy",
        "zero",
        "--episodes",
        "1",
        "--seed",
        "3",
        "--video",
        str(video),
        *cut,
    ]
    assert evaluate.main([*argv, "--no-plots", "--out", str(tmp_path / "out")]) == 0
    settings = env_settings({"n_trailers": 2})
    length = int(rollout(make_baseline("zero", settings, REVERSE), REVERSE, 1, 3).lengths[0])
    expected = length + 1 if steps is None else min(length, steps) + 1  # + the reset frame
    if suffix == ".gif":
        with Image.open(video) as gif:
            frames, size = gif.n_frames, gif.size
    else:
        reader = imageio.get_reader(video)
        frames, size = reader.count_frames(), tuple(reader.get_meta_data()["size"])
        reader.close()
    assert frames == expected and size == (600, 600)
    code = subprocess.run(
        [sys.executable, "-m", "agents.evaluate", *argv, "--no-plots", "--out", str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert (
        code.returncode == 2 and "argument --video" in code.stderr and "--overwrite" in code.stderr
    )


def test_train_errors_name_their_argument(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    broken_yaml = tmp_path / "broken"
    broken_yaml.mkdir()
    (broken_yaml / "ppo.yml").write_text("trailer_env/Reverse-v0: [unclosed\n  n_envs: 2\n")
    no_weights = model_copy(tmp_path / "no_weights")
    rewrite_zip(no_weights, {"policy.pth": None})
    exported = model_copy(tmp_path / "exported")
    base = ["--env", REVERSE, "--algo", "ppo"]
    hp_file = broken_yaml / "ppo.yml"
    cases = [
        (["--timesteps", "inf"], "argument --timesteps: expected a positive integer, got 'inf'"),
        (["--timesteps", "nan"], "argument --timesteps"),
        (["--run-dir", str(a_file)], f"argument --run-dir: {a_file} exists and is not a folder"),
        (["--resume", str(no_weights)], f"argument --resume: {no_weights} holds no policy weights"),
        (["--hyperparams", str(broken_yaml)], f"argument --hyperparams: {hp_file} is not valid"),
        (
            ["--export", str(exported), "--run-dir", str(tmp_path / "r")],
            f"argument --export: {exported} exists; pass --overwrite",
        ),
        (
            ["--backend", "rllib", "--resume", str(exported)],
            "argument --resume: not supported with --backend rllib",
        ),
        (["--address", "auto"], "argument --address: only with --backend rllib"),
    ]
    for argv, message in cases:
        code, err = _exit(train.main, [*base, *argv], capsys)
        assert code == 2 and message in err, (argv, err)
    assert not (tmp_path / "r").exists()  # refused before anything was written


def test_resuming_a_model_outside_a_run_starts_a_fresh_run_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A shipped model's folder never becomes a run folder."""
    assert run_dir_of_checkpoint(MODELS_DIR / "ppo_reverse_n2.zip") is None
    model = model_copy(tmp_path / "downloads", "ppo_reverse_n1")
    monkeypatch.chdir(tmp_path)
    argv = [
        "--env",
        REVERSE,
        "--algo",
        "ppo",
        "--n-trailers",
        "1",
        "--resume",
        str(model),
        "--timesteps",
        "1000",
        "--quiet",
        "--no-progress",
    ]
    # A total at or below the model's 3,260,416 steps would train nothing: refused.
    code, err = _exit(train.main, argv, capsys)
    assert code == 2 and "argument --timesteps" in err and "is at 3,260,416 steps" in err
    assert not (tmp_path / "runs").exists()
    # One more rollout of one env (256 steps), scored on two episodes.
    argv[argv.index("1000")] = "3260417"
    argv += ["--n-envs", "1", "--eval-episodes", "2"]
    assert train.main(argv) == 0
    assert sorted(path.name for path in model.parent.iterdir()) == [
        "ppo_reverse_n1.json",
        "ppo_reverse_n1.zip",
        "ppo_reverse_n1_vecnormalize.json",
    ]
    config = json.loads((tmp_path / "runs" / "reverse_n1_ppo_s0" / "config.json").read_text())
    assert config["env_kwargs"] == {"n_trailers": 1}
    # A second resume into that folder is not a continuation of that run: refused.
    code, err = _exit(train.main, argv, capsys)
    assert code == 2 and "already holds a run" in err


def test_main_refuses_to_replace_an_earlier_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "evaluations.csv").write_text("timesteps\n")
    code, err = _exit(main.main, ["--retrain", "--out", str(tmp_path)], capsys)
    assert code == 2 and "argument --out" in err and "--overwrite" in err
    assert (tmp_path / "run" / "evaluations.csv").read_text() == "timesteps\n"
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    code, err = _exit(main.main, ["--out", str(a_file)], capsys)
    assert code == 2 and f"argument --out: {a_file} exists and is not a folder" in err
