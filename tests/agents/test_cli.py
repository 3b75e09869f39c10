"""Exit codes and messages of the commands, and the evaluation's determinism under a seed."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from stable_baselines3 import PPO

from agents import evaluate, main, train
from agents.envs import make_sb3_env

REVERSE = "trailer_env/Reverse-v0"
ROOT = Path(__file__).resolve().parents[2]


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
        (["--env", REVERSE, "--algo", "ppo", "--forward-penalty", "-1"], "--forward-penalty"),
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
    model = tmp_path / "tiny.zip"
    venv = make_sb3_env(REVERSE, 2, {"n_trailers": 2}, seed=0)
    PPO("MlpPolicy", venv, policy_kwargs={"net_arch": [8]}, seed=0, device="cpu").save(model)
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
        cwd=ROOT, capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert done.returncode == 2 and "argument --algo" in done.stderr
