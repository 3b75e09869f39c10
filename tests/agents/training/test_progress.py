"""Progress reports: counts, ETA and total time; a training's bar ends at the real total."""

from __future__ import annotations

import io

import pytest
from stable_baselines3 import PPO

from agents.envs import make_sb3_env
from agents.progress import Progress, duration
from agents.training.callbacks import ProgressCallback


def test_a_log_gets_at_most_one_line_per_twentieth() -> None:
    stream = io.StringIO()
    with Progress(1000, "work", stream) as bar:
        for _ in range(1000):
            bar.advance()
    lines = stream.getvalue().splitlines()
    assert lines[0] == "work: 1000 steps"
    assert len(lines) == 1 + 20 + 1  # the header, one per 5 %, the total
    assert lines[-2].startswith("work: [1000/1000]")
    assert lines[-1].startswith("work: done, 1000/1000 in")
    assert duration(5.25) == "5.2 s" and duration(42) == "42 s" and duration(185) == "3 min 05 s"
    with pytest.raises(ValueError, match="total must be >= 0"):
        Progress(-1, "x")


def test_ppo_progress_ends_at_the_steps_it_really_takes(capsys: pytest.CaptureFixture[str]) -> None:
    venv = make_sb3_env("trailer_env/Reverse-v1", 4, {"n_trailers": 1}, seed=0)
    model = PPO("MlpPolicy", venv, n_steps=8, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.learn(50, callback=ProgressCallback("training"))
    assert model.num_timesteps == 64  # two rollouts of 8 steps x 4 envs
    err = capsys.readouterr().err
    assert "training: [64/64]" in err and "training: done, 64/64 in" in err
