"""The Ray RLlib backend: a short PPO run with one remote env runner on a local Ray (~20 s)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("ray.rllib")

import gymnasium as gym

from agents.artifacts.curves import read_curve
from agents.artifacts.rllib_files import POLICY_CARD, POLICY_WEIGHTS
from agents.commands import evaluate, train
from agents.policies.rllib import DEFAULT_MODULE, load_rllib_policy, module_class
from agents.training.config import load_hyperparams
from agents.training.rllib import RLLIB_ALGOS, make_rllib_env
from trailer_env.vector import ConvoyVectorEnv

REVERSE = "trailer_env/Reverse-v0"

#: One PPO iteration = 8 convoys x 128 steps; two iterations reach 2000 steps.
TINY_PPO = """\
trailer_env/Reverse-v0:
  n_envs: 8
  n_timesteps: 2000
  policy: MlpPolicy
  n_steps: 128
  batch_size: 256
  n_epochs: 2
  learning_rate: !!float 1e-3
  gamma: 0.99
  policy_kwargs: "dict(net_arch=[32, 32])"
  env_kwargs:
    n_trailers: 1
"""


def test_the_creator_builds_the_native_batch_or_one_env() -> None:
    batch = make_rllib_env({"env_id": REVERSE, "n_trailers": 2, "num_envs": 5})
    assert isinstance(batch.unwrapped, ConvoyVectorEnv) and batch.num_envs == 5
    single = make_rllib_env({"env_id": REVERSE, "n_trailers": 2})
    assert isinstance(single, gym.Env) and single.observation_space.shape == (8,)


def test_rllib_trains_with_a_remote_runner_and_its_checkpoint_evaluates(tmp_path: Path) -> None:
    import ray

    (tmp_path / "hp").mkdir()
    (tmp_path / "hp" / "ppo.yml").write_text(TINY_PPO)
    run = tmp_path / "run"
    argv = [
        "--backend",
        "rllib",
        "--env",
        REVERSE,
        "--algo",
        "ppo",
        "--n-trailers",
        "1",
        "--num-env-runners",
        "1",
        "--timesteps",
        "2000",
        "--hyperparams",
        str(tmp_path / "hp"),
        "--run-dir",
        str(run),
        "--quiet",
    ]
    assert train.main(argv) == 0
    assert not ray.is_initialized()  # the local Ray it started is shut down
    assert any((run / "ray_logs").iterdir())  # with its logs kept in the run folder
    config = json.loads((run / "config.json").read_text())
    assert config["backend"] == "rllib" and config["num_env_runners"] == 1
    # The remote runner stepped the native batched env, not 8 Python envs.
    ((env_class, native, node),) = config["runner_envs"]
    assert isinstance(node, str) and len(node) == 56  # a Ray node id (hex)
    assert native and env_class.endswith("VectorEnv")
    assert 2000 <= config["timesteps"] < 2000 + 1024 + 8  # one iteration ~ 1024 steps
    assert np.isfinite(config["episode_return_mean"]) and config["env_steps_per_s"] > 0
    rows = read_curve(run / "progress.csv")
    assert len(rows) == 2 and rows[-1]["timesteps"] == config["timesteps"]
    # Each episode of Reverse-v0 earns about 1 per step until it folds (~50 steps here).
    assert all(0 < row["episode_return_mean"] < 400 for row in rows)
    checkpoint = run / "checkpoint"
    assert (checkpoint / "rllib_checkpoint.json").is_file()
    assert (checkpoint / POLICY_WEIGHTS).is_file() and (checkpoint / POLICY_CARD).is_file()
    card = json.loads((checkpoint / POLICY_CARD).read_text())
    assert card["module_path"] == RLLIB_ALGOS["ppo"].module == DEFAULT_MODULE
    assert card["module"] == "DefaultPPOTorchRLModule"

    out = tmp_path / "eval"
    argv = ["--env", "trailer_env/Reverse-v0", "--n-trailers", "1", "--policy", str(checkpoint)]
    argv += ["zero", "--episodes", "10"]
    assert evaluate.main([*argv, "--no-plots", "--out", str(out)]) == 0
    document = json.loads((out / "results.json").read_text())
    model = document["policies"][0]
    assert model["name"] == "run" and model["kind"] == "model"
    assert model["training"]["algo"] == "ppo" and model["training"]["timesteps"] > 2000
    assert np.isfinite(model["mean_return"]) and 0.0 <= model["safe_rate"] <= 1.0
    # Same seeds, same numbers: the evaluation of the checkpoint is deterministic.
    assert evaluate.main([*argv, "--no-plots", "--out", str(tmp_path / "again")]) == 0
    assert (tmp_path / "again" / "results.json").read_bytes() == (out / "results.json").read_bytes()

    # The pickle-free export holds the learner's weights: RLlib's own (pickled)
    # checkpoint of the learner module, read with trust, acts identically.
    env = gym.make(REVERSE, n_trailers=1)
    spaces = (env.observation_space, env.action_space)
    safe = load_rllib_policy(checkpoint, *spaces)
    (checkpoint / POLICY_CARD).rename(tmp_path / "card.json")
    with pytest.raises(ValueError, match="--trust-pickle"):
        load_rllib_policy(checkpoint, *spaces)
    trusted = load_rllib_policy(checkpoint, *spaces, trust_pickle=True)
    obs = np.random.default_rng(0).uniform(-0.3, 0.3, (32, 6)).astype(np.float32)
    np.testing.assert_allclose(safe(obs), trusted(obs), rtol=0, atol=1e-6)
    assert np.all(np.abs(safe(obs)) <= 1.0)


def test_the_ppo_record_carries_the_sb3_entry_over(tmp_path: Path) -> None:
    (tmp_path / "ppo.yml").write_text(TINY_PPO)
    hp = load_hyperparams("ppo", REVERSE, tmp_path)
    record = RLLIB_ALGOS["ppo"]
    config = record.build_config(REVERSE, {"n_trailers": 1}, hp, 3, 2, 4)
    assert type(config).__name__ == "PPOConfig"
    # 8 x 128 steps per update over 2 runners of 4 envs: fragments of 128 steps.
    assert record.settings(config) == {
        "train_batch_size": 1024,
        "minibatch_size": 256,
        "num_epochs": 2,
        "lr": 1e-3,
        "gamma": 0.99,
        "lambda": 0.95,
        "clip_param": 0.2,
        "entropy_coeff": 0.0,
        "fcnet_hiddens": [32, 32],
    }
    assert module_class(record.module).__name__ == "DefaultPPOTorchRLModule"


@pytest.mark.parametrize(
    ("path", "match"),
    [
        ("os:system", "is not 'ray.rllib.<module>:<Class>'"),
        ("ray.rllib.core.columns", "is not 'ray.rllib.<module>:<Class>'"),
        ("ray.rllib.no_such_module:Thing", "does not exist"),
        ("ray.rllib.core.columns:Columns", "is not an RLModule"),
    ],
)
def test_a_policy_card_names_only_an_rllib_module(path: str, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        module_class(path)


def test_rllib_options_are_checked(capsys: pytest.CaptureFixture[str]) -> None:
    for argv, message in (
        (["--algo", "sac"], "argument --algo: --backend rllib trains ppo, not sac"),
        (["--algo", "ppo", "--num-env-runners", "-1"], "argument --num-env-runners"),
    ):
        with pytest.raises(SystemExit) as raised:
            train.main(["--backend", "rllib", "--env", REVERSE, *argv])
        assert raised.value.code == 2 and message in capsys.readouterr().err


def test_an_unreachable_cluster_exits_2_naming_the_address(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import ray

    def refuse(*args: object, **kwargs: object) -> None:
        raise ConnectionError("Failed to connect to Ray cluster at 10.0.0.9:6379")

    # (a real unreachable address makes Ray retry for minutes before it gives up)
    monkeypatch.setattr(ray, "init", refuse)
    argv = [
        "--backend",
        "rllib",
        "--env",
        REVERSE,
        "--algo",
        "ppo",
        "--address",
        "10.0.0.9:6379",
        "--run-dir",
        str(tmp_path / "run"),
    ]
    with pytest.raises(SystemExit) as raised:
        train.main(argv)
    err = capsys.readouterr().err
    assert raised.value.code == 2
    assert "argument --address: cannot connect to the Ray cluster at 10.0.0.9:6379" in err
    assert "RAY_AUTH_MODE=token" in err
