"""The policy registry: baselines by name, saved models by path, and their errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from stable_baselines3 import PPO, SAC

from agents.artifacts.cards import ModelCard
from agents.envs import env_settings, make_sb3_env
from agents.evaluation.tables import oracle_note, training_label
from agents.policies.baselines import (
    BASELINES,
    Baseline,
    Policy,
    applicable_baselines,
    make_baseline,
)
from agents.policies.registry import load_policy, policy_label
from agents.policies.sb3 import detect_algo
from trailer_env.settings import EnvSettings

REVERSE = "trailer_env/Reverse-v0"


def test_baselines_are_batched_and_bounded() -> None:
    settings = env_settings({"n_trailers": 2})
    obs = np.random.default_rng(0).uniform(-0.2, 0.2, (5, 8)).astype(np.float32)
    for name in ("zero", "random", "lqr"):
        actions = make_baseline(name, settings, REVERSE, 0)(obs)
        assert actions.shape == (5, 1) and actions.dtype == np.float32
        assert np.all(np.abs(actions) <= 1.0)
    assert np.all(make_baseline("zero", settings, REVERSE)(obs) == 0.0)
    first = make_baseline("random", settings, REVERSE, 3)(obs)
    assert np.array_equal(first, make_baseline("random", settings, REVERSE, 3)(obs))
    heading = make_baseline("heading-p", settings, "trailer_env/Heading-v0")
    assert heading(np.zeros((2, 11), np.float32)).shape == (2, 1)
    with pytest.raises(ValueError, match="Heading-v0"):
        make_baseline("heading-p", settings, REVERSE)
    with pytest.raises(ValueError, match="unknown baseline"):
        make_baseline("bang-bang", settings, REVERSE)
    assert set(BASELINES) == {
        "zero",
        "random",
        "lqr",
        "lqr-adaptive",
        "lqr-estimated",
        "heading-p",
        "mpc",
        "mpc-replay",
        "ilqr",
    }


def test_a_new_baseline_is_one_record(monkeypatch: pytest.MonkeyPatch) -> None:
    """A record that fits like the LQR runs wherever the LQR does, and the tables' note
    is the record's; the scenes' default lists are untouched."""

    def full_left(settings: EnvSettings, env_id: str, seed: int | None) -> Policy:
        return lambda obs: np.full((np.atleast_2d(obs).shape[0], 1), -1.0, np.float32)

    record = Baseline("full left", full_left, lambda steps: f"oracle, {steps} steps", "lqr")
    monkeypatch.setitem(BASELINES, "left", record)
    settings = env_settings({"n_trailers": 2})
    assert make_baseline("left", settings, REVERSE)(np.zeros((3, 8))).tolist() == [[-1.0]] * 3
    assert (
        oracle_note("left", 300) == "oracle, 300 steps"
        and training_label(ModelCard(), "left") == "oracle"
    )
    assert "left" not in applicable_baselines(REVERSE)
    assert oracle_note("lqr") == "-" and oracle_note("no-such-policy") == "-"
    assert oracle_note("mpc", 400) == (
        "oracle (exact model and state), 768k simulated steps per episode"
    )
    fitting_like = [name for name, baseline in BASELINES.items() if baseline.fits_like]
    assert {"lqr-adaptive", "lqr-estimated"} <= set(fitting_like) and fitting_like[-1] == "left"


def test_saved_models_load_by_path_with_their_algorithm(tmp_path: Path) -> None:
    venv = make_sb3_env(REVERSE, 2, {"n_trailers": 1}, seed=0)
    for cls, name in ((PPO, "ppo"), (SAC, "sac")):
        path = tmp_path / f"{name}_model.zip"
        cls("MlpPolicy", venv, policy_kwargs={"net_arch": [8]}, device="cpu").save(path)
        assert detect_algo(path) == name
        policy = load_policy(str(path), REVERSE, {"n_trailers": 1})
        actions = policy(np.zeros((3, 6), np.float32))
        assert actions.shape == (3, 1) and np.all(np.abs(actions) <= 1.0)
        assert policy_label(str(path)) == f"{name}_model"
    run = tmp_path / "ppo_run_s3"
    run.mkdir()
    (run / "config.json").write_text("{}")
    (tmp_path / "ppo_model.zip").rename(run / "best_model.zip")
    assert policy_label(str(run / "best_model.zip")) == "ppo_run_s3/best_model"  # which run's
    (run / "best_model.zip").rename(tmp_path / "ppo_model.zip")
    with pytest.raises(ValueError, match=r"expects observations of shape \(6,\)"):
        load_policy(str(tmp_path / "ppo_model.zip"), REVERSE, {"n_trailers": 2})


def test_unknown_policies_and_missing_files_are_named(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="unknown policy 'bogus'"):
        load_policy("bogus", REVERSE)
    with pytest.raises(FileNotFoundError, match="no model file"):
        load_policy(str(tmp_path / "absent.zip"), REVERSE)
    not_a_model = tmp_path / "text.zip"
    not_a_model.write_text("hello")
    with pytest.raises(ValueError, match="not a stable-baselines3 model"):
        load_policy(str(not_a_model), REVERSE)
    with pytest.raises(ValueError, match="unknown environment"):
        load_policy("zero", "CartPole-v1")
