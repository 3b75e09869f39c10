"""The start curriculum (`agents.train --start-curriculum`): the schedule, that it moves the
training starts only, its record, and its refusals."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from agents.algorithms.options import StartCurriculum
from agents.algorithms.recipes import recipe_name
from agents.artifacts.curves import read_curve
from agents.commands import train as train_command
from agents.training.config import TrainConfig, load_hyperparams
from agents.training.sb3 import train
from tests.agents.training.test_train import SMALL_PPO

V1 = "trailer_env/Reverse-v1"


def _folder(tmp_path: Path, normalize: bool = True) -> Path:
    folder = tmp_path / ("hyperparams" if normalize else "raw")
    folder.mkdir(exist_ok=True)
    text = SMALL_PPO.replace("Reverse-v0", "Reverse-v1")
    if not normalize:
        # The evaluations read observations through the training statistics, which the
        # training starts move: without them the step-0 evaluations can be compared.
        text = "\n".join(line for line in text.splitlines() if "normalize" not in line)
    (folder / "ppo.yml").write_text(text)
    return folder


def _run(tmp_path: Path, name: str, curriculum: tuple[float, int] | None) -> object:
    hp = load_hyperparams("ppo", V1, _folder(tmp_path, normalize=False))
    options = () if curriculum is None else (StartCurriculum(*curriculum),)
    config = TrainConfig.resolve(V1, "ppo", 1, 0, hp, timesteps=2048, options=options)
    return train(
        config, tmp_path / name, eval_freq=2048, eval_episodes=8, progress_bar=False, verbose=0
    )


def test_the_schedule_rises_linearly_then_holds() -> None:
    curriculum = StartCurriculum(0.2, 1000)
    scales = [curriculum.scale_at(t) for t in (0, 250, 500, 1000, 5000)]
    np.testing.assert_allclose(scales, [0.2, 0.4, 0.6, 1.0, 1.0], rtol=0, atol=1e-15)


def test_the_curriculum_moves_the_training_starts_and_not_the_evaluations(
    tmp_path: Path,
) -> None:
    plain = _run(tmp_path, "plain", None)
    # Rollouts of 16 x 64 = 1024 steps: drawn at 0.2 (step 0), then 0.6 (step 1024).
    taught: object = _run(tmp_path, "taught", (0.2, 2048))
    core = taught.get_env().unwrapped.core  # type: ignore[attr-defined]
    assert core.start_scale == pytest.approx(0.6, abs=1e-15)
    assert plain.get_env().unwrapped.core.start_scale == 1.0  # type: ignore[attr-defined]
    # The step-0 evaluation (same seed, same initial policy) is the scene's, unchanged...
    first = [read_curve(tmp_path / name / "evaluations.csv")[0] for name in ("plain", "taught")]
    assert first[0] == {**first[1], "wall_s": first[0]["wall_s"]}
    # ... while training on smaller starts led elsewhere.
    weights = [
        model.policy.state_dict()["action_net.weight"]  # type: ignore[attr-defined]
        for model in (plain, taught)
    ]
    assert not np.array_equal(weights[0].numpy(), weights[1].numpy())
    card = json.loads((tmp_path / "taught" / "final_model.json").read_text())
    assert card["start_curriculum"] == {"from": 0.2, "steps": 2048}
    assert recipe_name(card) == "ppo (32x32) + start curriculum"
    assert "start_curriculum" not in json.loads((tmp_path / "plain" / "config.json").read_text())


def _main(tmp_path: Path, *extra: str, env: str = V1) -> int:
    return train_command.main(
        ["--env", env, "--algo", "ppo", "--n-trailers", "1", "--hyperparams",
         str(_folder(tmp_path)), "--no-progress", "--quiet", "--eval-episodes", "4", *extra]
    )  # fmt: skip


@pytest.mark.parametrize(
    ("extra", "env", "message"),
    [
        (["--start-curriculum", "0.2,1000"], "trailer_env/Reverse-v0", "no perturbation size"),
        (["--start-curriculum", "1.0,1000"], V1, "expected FROM,STEPS"),
        (["--start-curriculum", "0.2"], V1, "expected FROM,STEPS"),
        (["--start-curriculum", "0.2,0"], V1, "expected FROM,STEPS"),
        (["--start-curriculum", "0.2,1000", "--backend", "rllib"], V1, "not supported"),
    ],
)
def test_refusals_touch_nothing(
    tmp_path: Path, extra: list[str], env: str, message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert_refused(tmp_path, extra, message, capsys, env)


def assert_refused(
    tmp_path: Path,
    extra: list[str],
    message: str,
    capsys: pytest.CaptureFixture[str],
    env: str = V1,
) -> None:
    """``agents.train`` with ``extra`` exits with 2, says ``message`` and writes nothing."""
    run = tmp_path / "refused"
    with pytest.raises(SystemExit) as refused:
        _main(tmp_path, "--timesteps", "2048", "--run-dir", str(run), *extra, env=env)
    assert refused.value.code == 2
    assert message in capsys.readouterr().err
    assert not run.exists()


def assert_resume_keeps(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    option: list[str],
    others: list[list[str]],
    message: str,
) -> Path:
    """A run trained with ``option`` refuses a --resume with any of ``others`` (saying
    ``message``, touching nothing) and goes on with ``option``; returns the run folder."""
    run = tmp_path / "run"
    args = ["--timesteps", "2048", "--checkpoint-freq", "1024", "--run-dir", str(run)]
    assert _main(tmp_path, *args, *option) == 0
    checkpoint = run / "checkpoints" / "ppo_1024_steps.zip"
    before = {p: p.stat().st_mtime_ns for p in run.rglob("*") if p.is_file()}
    for other in others:
        with pytest.raises(SystemExit):
            _main(tmp_path, "--resume", str(checkpoint), "--timesteps", "3072", *other)
        assert message in capsys.readouterr().err
    assert before == {p: p.stat().st_mtime_ns for p in run.rglob("*") if p.is_file()}
    assert _main(tmp_path, "--resume", str(checkpoint), "--timesteps", "3072", *option) == 0
    assert read_curve(run / "evaluations.csv")[-1]["timesteps"] == 3072
    return run


def test_a_resume_keeps_the_runs_curriculum(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    schedule = ["--start-curriculum", "0.5,4096"]
    others = [[], ["--start-curriculum", "0.5,8192"]]
    words = "trained with --start-curriculum 0.5,4096; resume it"
    assert_resume_keeps(tmp_path, capsys, schedule, others, words)
