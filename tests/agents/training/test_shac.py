"""SHAC through the differentiable twin: its losses fall, and its model is any PPO model."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import torch

from agents.artifacts.cards import read_model_card
from agents.commands.shac import main
from agents.evaluation.results import evaluate_policies
from agents.training.shac import SHACConfig, _Learner, gradient_agreement, train_shac

V1 = "trailer_env/Reverse-v1"


def test_the_losses_fall_on_a_tiny_budget() -> None:
    learner = _Learner(SHACConfig(n_trailers=1, num_envs=8, horizon=8, seed=0))
    figures = [learner.iterate() for _ in range(24)]
    actor = [row["actor_loss"] for row in figures]
    critic = [row["critic_loss"] for row in figures]
    assert all(np.isfinite(row["gradient_norm"]) for row in figures)
    # Measured (8 convoys, 24 windows of 8 steps): the critic's loss 4.5 at the first
    # window, 0.4-1.6 over the last six; the actor's loss -1.0 -> -2.3 to -3.5 (its
    # objective rises).
    assert np.mean(critic[-6:]) < 0.5 * critic[0]
    assert np.mean(actor[-6:]) < np.mean(actor[:6]) - 1.0
    assert learner.simulated_steps == 24 * 8 * 8


def test_the_exact_gradient_predicts_the_return_it_differentiates() -> None:
    # The observation statistics come from windows of random actions, so the rail's
    # columns get their real spread (standard deviations 0.12-0.2). From windows of the
    # zero action they sat at the variance floor (0.03): the policy read the mass
    # amplified several-fold, and its gradient stopped predicting the return.
    config = SHACConfig(n_trailers=1, num_envs=64, seed=0)
    rail = _Learner(config).obs_scale[4:6]  # n = 1: u, omega, sin, cos, then the rail
    assert float(rail.min()) > 0.1
    check = gradient_agreement(config, horizon=32, step=1e-3)
    # Measured: |g| 14.1, the return +0.0140 / -0.0143 for a predicted +-0.0141.
    assert check.up == pytest.approx(check.predicted, rel=0.1)
    assert check.down == pytest.approx(-check.predicted, rel=0.1)
    assert check.ratio == pytest.approx(1.0, abs=0.05)


def test_at_the_imitated_four_trailer_policy_the_gradient_is_not_the_slope() -> None:
    # Why the learner started from dagger_reverse_v1_n4 lowers it: there the exact
    # gradient of a 32-step window is three orders of magnitude steeper than the return
    # it differentiates, at every step length down to where float32 weights stop moving.
    config = SHACConfig(
        n_trailers=4, init_from="agents/models/dagger_reverse_v1_n4.zip", gamma=0.99
    )
    learned = gradient_agreement(config, horizon=32, step=1e-3)
    exact = gradient_agreement(config, horizon=32, step=1e-3, straight_through=False)
    # Measured: |g| 5.1e7 through the straight-through clips (the learner's), 7.1e3 exact;
    # a step of 1e-3 along either moves the return by under 1e-3 (predicted 5.1e4, 7.1).
    assert learned.gradient_norm > 1e6 and exact.gradient_norm > 1e3
    assert abs(learned.ratio) < 1e-4 and abs(exact.ratio) < 0.01


def test_the_target_critic_trails_the_critic_and_the_steps_anneal() -> None:
    config = SHACConfig(n_trailers=1, num_envs=8, horizon=8, iterations=4, target_critic=0.2)
    learner = _Learner(dataclasses.replace(config, anneal=True))
    critic = learner.critic_parameters
    before = [weight.detach().clone() for weight in learner.target.parameters()]
    learner.iterate()
    for target, old, new in zip(learner.target.parameters(), before, critic, strict=True):
        np.testing.assert_allclose(
            target.detach().numpy(), (0.2 * old + 0.8 * new.detach()).numpy(), rtol=1e-5, atol=1e-7
        )
    learner.iterate()  # the second window's steps: 3/4 of each rate
    assert learner.actor_optimizer.param_groups[0]["lr"] == pytest.approx(0.75 * config.actor_lr)
    assert learner.critic_optimizer.param_groups[0]["lr"] == pytest.approx(0.75 * config.critic_lr)


def test_the_bound_pull_is_the_gradient_of_its_penalty() -> None:
    # Past the bounds the straight-through clip passes the window's gradient as if the
    # mass moved, so nothing in the return stops the mean drifting outward; the pull
    # -w (|mean| - 1)^2 per step does. With every mean action near 3 its gradient on the
    # output bias is 2 w (|mean| - 1) times the window's mean discount.
    def bias_gradient(weight: float) -> float:
        config = SHACConfig(
            n_trailers=1, num_envs=16, horizon=8, action_bound_weight=weight, max_grad_norm=1e9
        )
        learner = _Learner(config)
        with torch.no_grad():
            learner.model.policy.action_net.bias.fill_(3.0)
        learner.iterate()
        gradient = learner.model.policy.action_net.bias.grad
        assert gradient is not None
        return float(gradient[0])

    discount = np.mean(0.999 ** np.arange(8))
    pull = bias_gradient(10.0) - bias_gradient(0.0)
    # Measured: 39.80 (the return's own gradient there 0.055).
    assert pull == pytest.approx(2.0 * 10.0 * 2.0 * discount, rel=5e-3)


def test_a_row_whose_gradient_is_not_finite_is_dropped_and_the_others_clipped() -> None:
    learner = _Learner(SHACConfig(n_trailers=1, num_envs=4, state_gradient_clip=2.0))
    gradient = torch.tensor(
        [[3.0, 4.0], [float("nan"), 1.0], [0.3, 0.4], [float("inf"), 0.0]], dtype=torch.float64
    )
    learner.dropped_rows = 0
    clipped = learner._clip_rows(gradient)
    wanted = [[1.2, 1.6], [0.0, 0.0], [0.3, 0.4], [0.0, 0.0]]
    np.testing.assert_allclose(clipped.numpy(), wanted, rtol=1e-12)
    assert learner.dropped_rows == 2


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
    header, *rows = (tmp_path / "run" / "evaluations.csv").read_text().splitlines()
    assert len(rows) == 2
    columns = dict(zip(header.split(","), rows[-1].split(","), strict=True))
    # The noisy actor's rate beside the mean action's, the share of mean actions past the
    # rail's bounds and the exploration noise: what tells a collapse's cause.
    assert 0.0 <= float(columns["sampled_safe_rate"]) <= 1.0
    assert 0.0 <= float(columns["saturated_share"]) <= 1.0
    assert float(columns["log_std"]) == pytest.approx(config.log_std_init, abs=0.01)


def test_bad_settings_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(ValueError, match="horizon"):
        SHACConfig(horizon=0)
    with pytest.raises(TypeError, match="num_envs"):
        SHACConfig(num_envs=8.0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="gamma"):
        SHACConfig(gamma=1.5)
    with pytest.raises(ValueError, match="net_arch"):
        SHACConfig(net_arch=())
    with pytest.raises(ValueError, match="state_gradient_clip"):
        SHACConfig(state_gradient_clip=-1.0)
    with pytest.raises(TypeError, match="state_gradient_clip"):
        SHACConfig(state_gradient_clip="1")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="action_bound_weight"):
        SHACConfig(action_bound_weight=-1.0)
    run = tmp_path / "run"
    run.mkdir()
    (run / "config.json").write_text("{}")
    with pytest.raises(SystemExit) as refused:
        main(["--n-trailers", "1", "--iterations", "1", "--run-dir", str(run)])
    assert refused.value.code == 2 and "--overwrite" in capsys.readouterr().err
    assert (run / "config.json").read_text() == "{}"
    fresh = tmp_path / "fresh"
    for flag, value, named in (
        ("--gamma", "2", "gamma"),
        ("--state-gradient-clip", "-1", "state_gradient_clip"),
        ("--actor-lr", "0", "actor_lr"),
        ("--target-critic", "1", "target_critic"),
    ):
        with pytest.raises(SystemExit) as refused:
            main(["--n-trailers", "1", flag, value, "--run-dir", str(fresh)])
        assert refused.value.code == 2 and named in capsys.readouterr().err
    assert not fresh.exists()
