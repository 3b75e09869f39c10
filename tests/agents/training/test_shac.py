"""SHAC through the differentiable twin: its losses fall, and its model is any PPO model."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from agents.artifacts.cards import read_model_card
from agents.commands.shac import main
from agents.evaluation.results import evaluate_policies
from agents.training.shac import SHACConfig, _Learner, train_shac

V1 = "trailer_env/Reverse-v1"


def test_the_losses_fall_on_a_tiny_budget() -> None:
    learner = _Learner(SHACConfig(n_trailers=1, num_envs=8, horizon=8, seed=0))
    figures = [learner.iterate() for _ in range(24)]
    actor = [row["actor_loss"] for row in figures]
    critic = [row["critic_loss"] for row in figures]
    assert all(np.isfinite(row["gradient_norm"]) for row in figures)
    # Measured (16 convoys, 40 windows): the critic's loss 15-21 -> 0.8-1.4, the actor's
    # -1.2 -> -2.4 to -2.9 (its objective rises).
    assert np.mean(critic[-6:]) < 0.5 * np.mean(critic[:6])
    assert np.mean(actor[-6:]) < np.mean(actor[:6])
    assert learner.simulated_steps == 24 * 8 * 8


def test_the_saved_model_evaluates_like_any_model(tmp_path: Path) -> None:
    config = SHACConfig(
        n_trailers=1,
        num_envs=4,
        horizon=4,
        iterations=2,
        eval_every=1,
        validation_episodes=2,
    )
    record = train_shac(config, tmp_path / "run", verbose=0, command=["test"])
    assert record["recipe"] == "shac" and record["timesteps"] == 2 * 4 * 4
    for name in ("best_model", "final_model"):
        path = tmp_path / "run" / f"{name}.zip"
        card = read_model_card(path)
        assert (card.algo, card.recipe, card.env_kwargs.n_trailers) == ("ppo", "shac", 1)
        assert card.host is not None and card.host.env_steps_per_s > 0
        assert (tmp_path / "run" / f"{name}_vecnormalize.json").is_file()
    (evaluation,) = evaluate_policies(
        [str(tmp_path / "run" / "best_model.zip")],
        V1,
        {"n_trailers": 1},
        2,
        50000,
        with_seeds=False,
        progress=False,
    )
    assert evaluation.summary.episodes == 2
    assert (tmp_path / "run" / "evaluations.csv").read_text().count("\n") == 3


def test_bad_settings_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(ValueError, match="horizon"):
        SHACConfig(horizon=0)
    with pytest.raises(TypeError, match="num_envs"):
        SHACConfig(num_envs=8.0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="gamma"):
        SHACConfig(gamma=1.5)
    with pytest.raises(ValueError, match="net_arch"):
        SHACConfig(net_arch=())
    run = tmp_path / "run"
    run.mkdir()
    (run / "config.json").write_text("{}")
    with pytest.raises(SystemExit) as refused:
        main(["--n-trailers", "1", "--iterations", "1", "--run-dir", str(run)])
    assert refused.value.code == 2 and "--overwrite" in capsys.readouterr().err
    assert (run / "config.json").read_text() == "{}"
