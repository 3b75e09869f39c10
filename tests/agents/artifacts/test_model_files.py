"""Model files without code execution: JSON statistics, SB3 zips loaded without unpickling."""

from __future__ import annotations

import base64
import json
import pickle
import zipfile
from pathlib import Path

import numpy as np
import pytest
from stable_baselines3.common.running_mean_std import RunningMeanStd
from stable_baselines3.common.vec_env import VecNormalize

from agents.artifacts.cards import read_model_card
from agents.artifacts.paths import stats_path
from agents.artifacts.sb3_zip import UnsafeFileError, safe_custom_objects
from agents.artifacts.shipped import MODELS_DIR
from agents.artifacts.stats import (
    STATS_FORMAT,
    frozen_normalizer,
    read_stats,
    restore_stats,
    save_stats,
)
from agents.envs import make_sb3_env
from agents.policies.extractors import feature_extractors
from agents.policies.registry import load_policy
from agents.policies.sb3 import load_model, load_stats
from tests.agents.helpers import Touch, rewrite_zip, tiny_model

REVERSE = "trailer_env/Reverse-v0"


def _tiny_model(folder: Path, n: int = 1) -> Path:
    return tiny_model(folder / "tiny.zip", n)


def _plant_pickle(path: Path, key: str, marker: Path) -> None:
    with zipfile.ZipFile(path) as archive:
        data = json.loads(archive.read("data"))
    payload = base64.b64encode(pickle.dumps(Touch(marker))).decode()
    data[key] = {**data[key], ":serialized:": payload}
    rewrite_zip(path, {"data": json.dumps(data).encode()})


def test_statistics_round_trip_exactly_through_json(tmp_path: Path) -> None:
    venv = VecNormalize(make_sb3_env(REVERSE, 4, {"n_trailers": 2}, seed=0), norm_reward=False)
    venv.reset()
    for _ in range(20):
        venv.step(np.random.default_rng(0).uniform(-1, 1, (4, 1)).astype(np.float32))
    path = save_stats(venv, tmp_path / "x_vecnormalize.json")
    document = read_stats(path)
    assert document.format == STATS_FORMAT and document.obs_rms.count > 20
    restored = frozen_normalizer(document, venv.observation_space)
    obs = np.random.default_rng(1).normal(size=(16, 8)).astype(np.float32)
    np.testing.assert_array_equal(restored.normalize_obs(obs), venv.normalize_obs(obs))
    fresh = VecNormalize(make_sb3_env(REVERSE, 2, {"n_trailers": 2}), norm_reward=False)
    restore_stats(fresh, document)
    fresh_rms, rms = fresh.obs_rms, venv.obs_rms
    assert isinstance(fresh_rms, RunningMeanStd) and isinstance(rms, RunningMeanStd)
    np.testing.assert_array_equal(fresh_rms.var, rms.var)
    assert fresh_rms.count == rms.count
    with pytest.raises(ValueError, match=r"shape \(8,\), but the environment gives \(6,\)"):
        restore_stats(VecNormalize(make_sb3_env(REVERSE, 1, {"n_trailers": 1})), document)


def test_damaged_statistics_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "x_vecnormalize.json"
    path.write_text("{not json")
    with pytest.raises(ValueError, match="not a statistics JSON file"):
        read_stats(path)
    good = json.loads((MODELS_DIR / "ppo_reverse_n2_vecnormalize.json").read_text())
    good["obs_rms"]["var"][0] = -1.0
    path.write_text(json.dumps(good))
    with pytest.raises(ValueError, match="negative-variance"):
        read_stats(path)


def test_shipped_models_have_json_statistics_and_no_pickles() -> None:
    zips = sorted(MODELS_DIR.glob("*.zip"))
    seeds = sorted((MODELS_DIR / "seeds").glob("*.zip"))
    # With the generalist, the three sequence generalists from the planner (ConvoyEncoder:
    # n = 1-3, n = 1-6 and n = 1-6 trained with the mirror) and the two distilled from the
    # specialists (n = 1-3, n = 1-6).
    # With the students that adapt (n = 1, 2, 3 and one policy for n = 1-3, mismatch20)
    # and their fifteen privileged teachers (nine first ones, six fine-tuned at n = 2, 3).
    teachers = sorted((MODELS_DIR / "teachers").glob("*.zip"))
    assert len(zips) == 34 and len(teachers) == 15 and not list(MODELS_DIR.glob("**/*.pkl"))
    # 3 training seeds of each Reverse-v1 (DAgger, PPO), Dock, Coast model, of the
    # distilled n = 1-6 policy and of the students that adapt.
    assert len(seeds) == 48
    for model in zips + seeds + teachers:
        card = read_model_card(model)
        sequence = card.env_kwargs.observation == "trailers"
        if sequence:
            # The encoder scales its own inputs: no observation statistics.
            assert not stats_path(model).exists()
        else:
            document = read_stats(stats_path(model))
            assert document.norm_obs is True and document.norm_reward is False
        # Every pickled entry of the zip has a safe replacement: nothing is unpickled.
        assert card.env_id is not None and card.algo is not None
        probe = make_sb3_env(card.env_id, 1, card.env_kwargs.as_kwargs())
        custom = safe_custom_objects(
            model,
            card.algo,
            probe.observation_space,
            probe.action_space,
            extractors=feature_extractors() if sequence else None,
        )
        assert {"policy_class", "observation_space", "action_space"} <= set(custom)


def test_a_pickle_planted_in_the_zip_is_not_run(tmp_path: Path) -> None:
    model = _tiny_model(tmp_path)
    marker = tmp_path / "ran"
    _plant_pickle(model, "observation_space", marker)
    _plant_pickle(model, "lr_schedule", marker)
    policy = load_policy(str(model), REVERSE, {"n_trailers": 1})
    assert policy(np.zeros((2, 6), np.float32)).shape == (2, 1)
    assert not marker.exists()
    # SB3 itself runs it (then fails: the payload is no space): --trust-pickle allows that.
    with pytest.raises(ValueError, match="not a Gymnasium space"):
        load_model(model, "ppo", env_id=REVERSE, env_kwargs={"n_trailers": 1}, trust_pickle=True)
    assert marker.exists()


def test_an_unknown_pickled_entry_is_refused(tmp_path: Path) -> None:
    model = _tiny_model(tmp_path)
    with zipfile.ZipFile(model) as archive:
        data = json.loads(archive.read("data"))
    data["surprise"] = {":serialized:": base64.b64encode(pickle.dumps(1)).decode()}
    rewrite_zip(model, {"data": json.dumps(data).encode()})
    with pytest.raises(UnsafeFileError, match=r"entry 'surprise' is a pickle.*--trust-pickle"):
        load_policy(str(model), REVERSE, {"n_trailers": 1})


def test_pickled_statistics_need_trust(tmp_path: Path) -> None:
    model = _tiny_model(tmp_path)
    marker = tmp_path / "ran"
    stats_path(model).with_suffix(".pkl").write_bytes(pickle.dumps(Touch(marker)))
    with pytest.raises(UnsafeFileError, match=r"tiny_vecnormalize\.pkl.*--trust-pickle"):
        load_policy(str(model), REVERSE, {"n_trailers": 1})
    assert not marker.exists()
    with pytest.raises(AttributeError):  # the "statistics" were only a payload
        load_stats(model, trust_pickle=True)
    assert marker.exists()


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        ({"policy.pth": b"\x00garbage weights\xff" * 10}, "cannot load model"),
        ({"policy.pth": None}, r"holds no policy weights \(policy\.pth\)"),
        ({"data": b"[1, 2]"}, "not a stable-baselines3 model"),
    ],
)
def test_damaged_zips_raise_value_errors(
    tmp_path: Path, damage: dict[str, bytes | None], message: str
) -> None:
    model = _tiny_model(tmp_path)
    rewrite_zip(model, damage)
    with pytest.raises(ValueError, match=message):
        load_policy(str(model), REVERSE, {"n_trailers": 1})


def test_a_malformed_policy_class_entry_is_a_value_error(tmp_path: Path) -> None:
    model = _tiny_model(tmp_path)
    with zipfile.ZipFile(model) as archive:
        data = json.loads(archive.read("data"))
    data["policy_class"] = "MlpPolicy"
    rewrite_zip(model, {"data": json.dumps(data).encode()})
    with pytest.raises(ValueError, match="policy_class"):
        load_policy(str(model), REVERSE, {"n_trailers": 1})
