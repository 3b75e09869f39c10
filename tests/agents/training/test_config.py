"""The rl-zoo3 hyperparameter files and their parser."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch.nn

from agents.algorithms.options import Shaping
from agents.artifacts.shipped import MODELS_DIR
from agents.envs import ENV_IDS
from agents.training.config import (
    HYPERPARAMS_DIR,
    TrainConfig,
    load_hyperparams,
    parse_policy_kwargs,
    raw_entry,
)

V0 = "trailer_env/Reverse-v0"


@pytest.mark.parametrize("algo", ["ppo", "sac", "td3"])
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_scene_has_hyperparameters(algo: str, env_id: str) -> None:
    hp = load_hyperparams(algo, env_id)
    assert hp.n_envs >= 1 and hp.n_timesteps >= 1000
    assert hp.policy == "MlpPolicy"
    assert hp.env_kwargs == {"n_trailers": 2}
    assert hp.algo_kwargs["policy_kwargs"]["net_arch"] == [64, 64]
    assert hp.normalize == {"norm_obs": True, "norm_reward": False}


def test_the_gsde_recipe_differs_from_ppo_yml_only_in_exploration() -> None:
    reverse = "trailer_env/Reverse-v1"
    plain = load_hyperparams("ppo", reverse)
    gsde = load_hyperparams("ppo", reverse, HYPERPARAMS_DIR / "gsde")
    assert gsde.shaping is None and plain.shaping is None
    assert gsde.algo_kwargs.pop("use_sde") is True and gsde.algo_kwargs.pop("sde_sample_freq") == 4
    assert gsde.algo_kwargs.pop("policy_kwargs") == {"net_arch": [64, 64], "log_std_init": -2.0}
    plain.algo_kwargs.pop("policy_kwargs")
    assert gsde.algo_kwargs == plain.algo_kwargs
    assert (gsde.n_envs, gsde.normalize) == (plain.n_envs, plain.normalize)


@pytest.mark.parametrize(
    ("env_id", "n_trailers"), [("trailer_env/Reverse-v1", 3), ("trailer_env/Coast-v0", 2)]
)
def test_the_wide_and_coast_gsde_recipes_change_only_what_they_name(
    env_id: str, n_trailers: int
) -> None:
    plain = load_hyperparams("ppo", env_id)
    gsde = load_hyperparams("ppo", env_id, HYPERPARAMS_DIR / "gsde")
    plain_policy = plain.algo_kwargs.pop("policy_kwargs")
    gsde_policy = gsde.algo_kwargs.pop("policy_kwargs")
    assert gsde_policy == {**plain_policy, "log_std_init": -2.0}
    assert gsde.algo_kwargs == {**plain.algo_kwargs, "use_sde": True, "sde_sample_freq": 4}
    wide = load_hyperparams("ppo", env_id, HYPERPARAMS_DIR / "gsde_wide")
    assert wide.algo_kwargs.pop("policy_kwargs") == {**gsde_policy, "net_arch": [256, 256]}
    assert wide.algo_kwargs == gsde.algo_kwargs
    assert wide.env_kwargs == {"n_trailers": n_trailers}


def test_the_wide_dock_recipe_is_the_plain_one_with_gsde_and_wider_networks() -> None:
    plain = load_hyperparams("ppo", "trailer_env/Dock-v0")
    wide = load_hyperparams("ppo", "trailer_env/Dock-v0", HYPERPARAMS_DIR / "gsde_wide")
    plain_policy = plain.algo_kwargs.pop("policy_kwargs")
    assert wide.algo_kwargs.pop("policy_kwargs") == {
        **plain_policy,
        "log_std_init": -2.0,
        "net_arch": [256, 256],
    }
    assert wide.algo_kwargs == {**plain.algo_kwargs, "use_sde": True, "sde_sample_freq": 4}
    assert wide.env_kwargs == plain.env_kwargs == {"n_trailers": 2}


@pytest.mark.parametrize(
    ("model", "env_id"),
    [
        ("ppo_reverse_v1_n3", "trailer_env/Reverse-v1"),
        ("ppo_coast_n2", "trailer_env/Coast-v0"),
        ("ppo_dock_n2", "trailer_env/Dock-v0"),
    ],
)
def test_the_committed_wide_agents_are_the_wide_recipe(model: str, env_id: str) -> None:
    card = json.loads((MODELS_DIR / f"{model}.json").read_text())
    wide = load_hyperparams("ppo", env_id, HYPERPARAMS_DIR / "gsde_wide")
    recorded = dict(card["hyperparams"])
    assert recorded.pop("policy_kwargs") == wide.algo_kwargs.pop("policy_kwargs")
    assert recorded == wide.algo_kwargs
    assert card["env_kwargs"] == wide.env_kwargs and card["n_envs"] == wide.n_envs


def test_policy_kwargs_strings_parse_without_eval() -> None:
    parsed = parse_policy_kwargs(
        "dict(net_arch=dict(pi=[64, 64], vf=[32]), log_std_init=-1.0, activation_fn=nn.Tanh)"
    )
    assert parsed == {
        "net_arch": {"pi": [64, 64], "vf": [32]},
        "log_std_init": -1.0,
        "activation_fn": torch.nn.Tanh,
    }
    with pytest.raises(ValueError, match="unsupported expression"):
        parse_policy_kwargs("dict(x=__import__('os').getcwd())")
    with pytest.raises(ValueError, match="must be a dict"):
        parse_policy_kwargs("[1, 2]")


def test_linear_schedule_and_unknown_entries(tmp_path: Path) -> None:
    (tmp_path / "ppo.yml").write_text(
        "trailer_env/Reverse-v0:\n  n_timesteps: !!float 1e4\n  learning_rate: lin_0.001\n"
    )
    hp = load_hyperparams("ppo", "trailer_env/Reverse-v0", tmp_path)
    schedule = hp.algo_kwargs["learning_rate"]
    assert schedule(1.0) == pytest.approx(1e-3) and schedule(0.5) == pytest.approx(5e-4)
    assert hp.n_timesteps == 10_000 and hp.normalize is None
    with pytest.raises(ValueError, match="no entry for trailer_env/Dock-v0 and no 'default' entry"):
        load_hyperparams("ppo", "trailer_env/Dock-v0", tmp_path)
    with pytest.raises(FileNotFoundError, match=r"sac\.yml"):
        load_hyperparams("sac", "trailer_env/Reverse-v0", tmp_path)
    assert (HYPERPARAMS_DIR / "ppo.yml").is_file()


def test_shaping_entries_name_a_potential_and_its_numbers(tmp_path: Path) -> None:
    (tmp_path / "ppo.yml").write_text(
        "trailer_env/Reverse-v1:\n  shaping: lqr\n"
        "trailer_env/Reverse-v0:\n  shaping: \"dict(potential='lqr', scale=0.5)\"\n"
    )
    assert load_hyperparams("ppo", "trailer_env/Reverse-v1", tmp_path).shaping == Shaping("lqr")
    hp = load_hyperparams("ppo", "trailer_env/Reverse-v0", tmp_path)
    assert hp.shaping == Shaping("lqr", 0.5) and "shaping" not in hp.algo_kwargs
    assert hp.shaping.record() == {"shaping": {"potential": "lqr", "scale": 0.5}}
    assert Shaping.from_setting("none") is None
    for bad, words in (
        ("energy", "potential among"),
        ("dict(potential='lqr', weight=2)", "no 'weight'"),
        ("dict(potential='lqr', scale='big')", "scale must be a finite number"),
        ("dict('lqr')", "dict\\(name=value"),
        (3, "a potential or a dict"),
    ):
        with pytest.raises(ValueError, match=words):
            Shaping.from_setting(bad)
    # An SB3 run without --shaping takes the entry's; its own option goes over it.
    sb3 = TrainConfig.resolve(V0, "ppo", 2, 0, hp, timesteps=2048)
    assert sb3.options == (Shaping("lqr", 0.5),)
    assert sb3.document()["shaping"] == {"potential": "lqr", "scale": 0.5}
    given = (Shaping("lqr"),)
    assert TrainConfig.resolve(V0, "ppo", 2, 0, hp, timesteps=2048, options=given).options == given
    rllib = TrainConfig.resolve(V0, "ppo", 2, 0, hp, timesteps=2048, backend="rllib")
    assert rllib.options == () and "shaping" not in rllib.document()
    (tmp_path / "ppo.yml").write_text("trailer_env/Reverse-v1:\n  shaping: energy\n")
    with pytest.raises(ValueError, match="entry trailer_env/Reverse-v1: shaping needs a potential"):
        load_hyperparams("ppo", "trailer_env/Reverse-v1", tmp_path)


def test_an_entry_may_name_the_multi_input_policy_and_the_encoder(tmp_path: Path) -> None:
    from agents.policies.convoy_encoder import ConvoyEncoder

    (tmp_path / "ppo.yml").write_text(
        "trailer_env/Reverse-v1:\n"
        "  policy: MultiInputPolicy\n"
        "  env_kwargs: {n_trailers: 2, observation: trailers}\n"
        '  policy_kwargs: "dict(features_extractor_class=ConvoyEncoder, net_arch=[16])"\n'
    )
    hp = load_hyperparams("ppo", "trailer_env/Reverse-v1", tmp_path)
    assert hp.policy == "MultiInputPolicy"
    assert hp.env_kwargs == {"n_trailers": 2, "observation": "trailers"}
    assert hp.algo_kwargs["policy_kwargs"] == {
        "features_extractor_class": ConvoyEncoder,
        "net_arch": [16],
    }


def test_an_id_without_an_entry_reads_the_default(tmp_path: Path) -> None:
    (tmp_path / "ppo.yml").write_text(
        "default: &default\n  n_timesteps: 5000\n  gamma: 0.9\n"
        "trailer_env/Reverse-v0:\n  <<: *default\n  gamma: 0.999\n"
    )
    named = load_hyperparams("ppo", "trailer_env/Reverse-v0", tmp_path)
    assert named.n_timesteps == 5000 and named.algo_kwargs == {"gamma": 0.999}
    fallback = load_hyperparams("ppo", "trailer_env/Dock-v0", tmp_path)
    assert fallback.n_timesteps == 5000 and fallback.algo_kwargs == {"gamma": 0.9}
    assert raw_entry("ppo", "trailer_env/Dock-v0", tmp_path) == {
        "n_timesteps": 5000,
        "gamma": 0.9,
    }
    # A bad default is reported as the default entry's, not the id's.
    (tmp_path / "ppo.yml").write_text("default:\n  n_envs: 0\n")
    with pytest.raises(ValueError, match=r"entry default: n_envs must be an integer"):
        load_hyperparams("ppo", "trailer_env/Dock-v0", tmp_path)
    (tmp_path / "ppo.yml").write_text("trailer_env/Reverse-v0:\n  n_envs: 1\n")
    with pytest.raises(ValueError, match="no entry for trailer_env/Dock-v0 and no 'default' entry"):
        raw_entry("ppo", "trailer_env/Dock-v0", tmp_path)


def test_a_scene_without_entries_trains_on_the_committed_defaults() -> None:
    """Every committed file's default is what a scene without an entry of its own reads."""
    for algo in ("ppo", "ppo_lag", "sac", "td3"):
        assert raw_entry(algo, "trailer_env/NoSuchScene-v0") == raw_entry(algo, "default")
        assert load_hyperparams(algo, "trailer_env/NoSuchScene-v0").env_kwargs == {"n_trailers": 2}
