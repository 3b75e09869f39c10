"""PPO-Lagrangian: the multiplier's update rule, the penalised rollout, training and resuming."""

from __future__ import annotations

import csv
import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from stable_baselines3.common.vec_env import VecEnvWrapper

from agents.algorithms import ALGOS, algo_class
from agents.algorithms.ppo_lagrangian import (
    PPOLagrangian,
    info_column,
    lagrange_update,
    penalised_reward,
)
from agents.commands import train
from agents.envs import make_sb3_env
from agents.policies.registry import load_policy
from agents.policies.sb3 import detect_algo, load_model
from agents.training.config import load_hyperparams

REVERSE = "trailer_env/Reverse-v1"

#: A tiny PPO-Lagrangian (one trailer: the singular margin is 1, so the cost is always 0
#: and lambda falls by lambda_lr * cost_limit = 0.2 per rollout, 512 steps, until 0).
TINY = """\
trailer_env/Reverse-v1:
  n_envs: 8
  policy: MlpPolicy
  normalize: "dict(norm_obs=True, norm_reward=False)"
  n_steps: 64
  batch_size: 256
  n_epochs: 1
  gamma: 0.99
  policy_kwargs: "dict(net_arch=[8], log_std_init=-1.0)"
  cost_limit: 2.0
  lambda_lr: 0.1
  lambda_init: 1.0
"""


@pytest.mark.parametrize(
    ("multiplier", "cost", "limit", "lr", "expected"),
    [
        (1.0, 7.0, 5.0, 0.1, 1.2),  # over the limit: rises by lr * (7 - 5)
        (1.0, 2.0, 5.0, 0.1, 0.7),  # under: falls by lr * (5 - 2)
        (0.1, 0.0, 5.0, 0.1, 0.0),  # falls, but not below 0
        (0.0, 5.0, 5.0, 0.1, 0.0),  # at the limit: stays
        (2.0, 30.0, 25.0, 0.035, 2.175),
    ],
)
def test_lagrange_update_rule(
    multiplier: float, cost: float, limit: float, lr: float, expected: float
) -> None:
    assert lagrange_update(multiplier, cost, limit, lr) == pytest.approx(expected, abs=1e-12)


def test_penalised_reward_is_omnisafes_normalisation() -> None:
    reward = np.array([1.0, 2.0, -1.0])
    cost = np.array([0.0, 1.0, 1.0])
    np.testing.assert_allclose(penalised_reward(reward, cost, 0.0), reward)
    np.testing.assert_allclose(penalised_reward(reward, cost, 3.0), [0.25, -0.25, -1.0])


def test_registry_record_and_bad_arguments() -> None:
    assert ALGOS["ppo_lag"].policy_module == ALGOS["ppo"].policy_module
    assert ALGOS["ppo_lag"].off_policy is False and algo_class("ppo_lag") is PPOLagrangian
    with pytest.raises(ValueError, match="unknown algorithm 'ppo_lagr'"):
        algo_class("ppo_lagr")
    venv = make_sb3_env(REVERSE, 2, {"n_trailers": 1}, seed=0)
    for kwargs, error, message in (
        ({"lambda_lr": 0.0}, ValueError, "lambda_lr must be a finite number > 0, got 0.0"),
        ({"cost_limit": -1.0}, ValueError, "cost_limit must be a finite number >= 0"),
        ({"lambda_init": float("nan")}, ValueError, "lambda_init must be a finite number"),
        ({"cost_limit": "5"}, TypeError, "cost_limit must be a number, got str"),
        ({"lambda_init": True}, TypeError, "lambda_init must be a number, got bool"),
    ):
        with pytest.raises(error, match=message):
            PPOLagrangian("MlpPolicy", venv, **kwargs)


def test_the_hyperparameter_file_has_ppos_defaults_plus_three() -> None:
    ppo = load_hyperparams("ppo", REVERSE)
    lag = load_hyperparams("ppo_lag", REVERSE)
    extra = {key: lag.algo_kwargs.pop(key) for key in ("cost_limit", "lambda_lr", "lambda_init")}
    assert extra == {"cost_limit": 1.0, "lambda_lr": 0.05, "lambda_init": 0.0}
    assert lag.algo_kwargs.keys() == ppo.algo_kwargs.keys()
    assert (lag.n_envs, lag.normalize, lag.algo_kwargs["gamma"]) == (64, ppo.normalize, 0.999)


def test_batch_infos_column_is_read_without_dicts() -> None:
    venv = make_sb3_env(REVERSE, 3, {"n_trailers": 2}, seed=0)
    venv.reset()
    _, _, _, infos = venv.step(np.zeros((3, 1), dtype=np.float32))
    column = info_column(infos, "cost")
    assert column.shape == (3,) and list(column) == [info["cost"] for info in infos]
    with pytest.raises(KeyError, match="PPO-Lagrangian constrains info\\['nope'\\]"):
        info_column(infos, "nope")
    with pytest.raises(KeyError, match="no 'cost'"):
        info_column([{}], "cost")


class _UnitCost(VecEnvWrapper):
    """Every step costs 1 (so an episode's cost is its length); records the raw rewards."""

    def __init__(self, venv: Any) -> None:
        super().__init__(venv)
        self.rewards: list[np.ndarray] = []

    def reset(self) -> Any:
        return self.venv.reset()

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = self.venv.step_wait()
        infos = [{**info, "cost": 1.0} for info in infos]
        self.rewards.append(rewards.copy())
        return obs, rewards, dones, infos


def test_one_rollout_updates_lambda_and_penalises_the_buffer() -> None:
    """Episodes cost their length: lambda moves by lr * (mean length - limit), and the
    buffer's rewards are (r - lambda) / (1 + lambda) with that new lambda."""
    venv = _UnitCost(make_sb3_env(REVERSE, 4, {"n_trailers": 1}, seed=0))
    model = PPOLagrangian(
        "MlpPolicy",
        venv,
        n_steps=128,
        batch_size=128,
        n_epochs=1,
        seed=0,
        device="cpu",
        policy_kwargs={"net_arch": [8]},
        cost_limit=10.0,
        lambda_lr=0.01,
        lambda_init=0.5,
    )
    model.learn(total_timesteps=512)
    lengths = [episode["l"] for episode in model.ep_info_buffer]
    assert len(lengths) > 4  # random actions fold one trailer within ~50 steps
    expected = 0.5 + 0.01 * (np.mean(lengths) - 10.0)
    assert model.lagrange_multiplier == pytest.approx(expected, rel=1e-12)
    raw = np.array(venv.rewards)
    penalised = (raw - expected) / (1.0 + expected)
    # No episode is cut by the time limit in 128 steps: no bootstrap term is added.
    np.testing.assert_allclose(model.rollout_buffer.rewards, penalised, atol=1e-6)  # float32


def _lambdas(progress: Path) -> list[float]:
    with progress.open() as handle:
        return [
            float(row["lagrangian/lambda"])
            for row in csv.DictReader(handle)
            if row.get("lagrangian/lambda")
        ]


def _train(tmp_path: Path, *extra: str) -> int:
    return train.main(
        [
            "--env",
            REVERSE,
            "--algo",
            "ppo_lag",
            "--n-trailers",
            "1",
            "--seed",
            "0",
            "--hyperparams",
            str(tmp_path / "hp"),
            "--no-progress",
            "--quiet",
            "--eval-episodes",
            "4",
            "--run-dir",
            str(tmp_path / "run"),
            *extra,
        ]
    )


def test_train_logs_saves_and_resumes_lambda(tmp_path: Path) -> None:
    (tmp_path / "hp").mkdir()
    (tmp_path / "hp" / "ppo_lag.yml").write_text(TINY)
    run = tmp_path / "run"
    assert _train(tmp_path, "--timesteps", "1536", "--checkpoint-freq", "1024") == 0
    # Three rollouts of 512 steps, each cost 0 < 2: 1.0 - 0.2 per rollout.
    assert _lambdas(run / "logs" / "from_0" / "progress.csv") == pytest.approx([0.8, 0.6, 0.4])
    assert (run / "evaluations.csv").is_file() and (run / "final_model.zip").is_file()
    final = load_model(run / "final_model.zip")
    assert type(final) is PPOLagrangian and final.lagrange_multiplier == pytest.approx(0.4)
    assert json.loads((run / "final_model.json").read_text())["algo"] == "ppo_lag"
    # The checkpoint at 1024 steps was saved during the second rollout, before its update.
    checkpoint = run / "checkpoints" / "ppo_lag_1024_steps.zip"
    with zipfile.ZipFile(checkpoint) as archive:
        data = json.loads(archive.read("data"))
    assert (data["lagrange_multiplier"], data["cost_limit"]) == pytest.approx((0.8, 2.0))
    assert detect_algo(checkpoint) == "ppo_lag"  # no card: told by its data entry
    assert _train(tmp_path, "--timesteps", "2048", "--resume", str(checkpoint)) == 0
    assert _lambdas(run / "logs" / "from_1024" / "progress.csv") == pytest.approx([0.6, 0.4])
    # A PPO policy for agents.evaluate, loaded without unpickling anything.
    assert detect_algo(run / "final_model.zip") == "ppo_lag"
    policy = load_policy(str(run / "final_model.zip"), REVERSE, {"n_trailers": 1})
    action = policy(np.zeros((2, 6), dtype=np.float32))
    assert action.shape == (2, 1)
