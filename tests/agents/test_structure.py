"""The shared pieces: CLI parsers, the run's TrainConfig, the run folder, scene-table look-ups."""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import pytest

from agents.artifacts.cards import ModelCard
from agents.artifacts.paths import model_stem
from agents.artifacts.run_folder import (
    RunFolderError,
    choose_run_dir,
    default_run_dir,
    write_config,
)
from agents.commands import options as cli
from agents.envs import ENV_IDS, env_settings, scene_of, scene_title
from agents.evaluation.results import curve_metric, default_baselines
from agents.policies.baselines import make_baseline
from agents.training.config import TrainConfig, load_hyperparams
from trailer_env.registry import core_class_of

REVERSE = "trailer_env/Reverse-v0"


@pytest.mark.parametrize(
    ("parse", "text", "value"),
    [
        (cli.positive_int, "1e6", 1_000_000),
        (cli.positive_int, "7", 7),
        (cli.non_negative_int, "0", 0),
        (cli.at_least(1), "3", 3),
        (cli.positive_float, "0.25", 0.25),
    ],
)
def test_parsers_accept(parse, text: str, value: float) -> None:  # type: ignore[no-untyped-def]
    assert parse(text) == value


@pytest.mark.parametrize(
    ("parse", "text", "message"),
    [
        (cli.positive_int, "1.5", "expected a positive integer, got '1.5'"),
        (cli.positive_int, "0", "expected a positive integer, got '0'"),
        (cli.positive_int, "inf", "expected a positive integer, got 'inf'"),
        (cli.non_negative_int, "-1", "expected an integer >= 0, got '-1'"),
        (cli.at_least(0), "-2", "must be >= 0, got -2"),
        (cli.at_least(1), "two", "expected an integer >= 1, got 'two'"),
        (cli.positive_float, "nan", "expected a positive number, got 'nan'"),
        (cli.positive_float, "0", "expected a positive number, got '0'"),
    ],
)
def test_parsers_refuse_naming_the_value(parse, text: str, message: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(argparse.ArgumentTypeError, match=message.replace(".", r"\.")):
        parse(text)


def test_shared_options_exit_2_naming_the_argument(capsys: pytest.CaptureFixture[str]) -> None:
    parser = argparse.ArgumentParser()
    cli.add_env(parser)
    cli.add_n_trailers(parser)
    cli.add_seed(parser, 0, "seed")
    args = parser.parse_args(["--env", REVERSE])
    assert (args.env, args.n_trailers, args.seed) == (REVERSE, 2, 0)
    with pytest.raises(SystemExit) as raised:
        parser.parse_args(["--env", REVERSE, "--seed", "-3"])
    assert raised.value.code == 2
    assert "argument --seed: expected an integer >= 0, got '-3'" in capsys.readouterr().err


def test_train_config_is_one_frozen_record() -> None:
    hp = load_hyperparams("ppo", REVERSE)
    config = TrainConfig.resolve(REVERSE, "ppo", 3, 7, hp, command=["python", "-m", "x"])
    assert config.budget == hp.n_timesteps and config.n_envs == hp.n_envs
    assert config.env_kwargs == {**hp.env_kwargs, "n_trailers": 3}
    document = config.document()
    assert sorted(document) == [
        "algo",
        "budget",
        "command",
        "env_id",
        "env_kwargs",
        "hyperparams",
        "n_envs",
        "normalize",
        "policy",
        "seed",
    ]
    assert document["seed"] == 7 and document["command"] == ["python", "-m", "x"]
    json.dumps(document)  # JSON-ready (schedules and classes by name)
    rllib = dataclasses.replace(config, backend="rllib").document()
    assert rllib["backend"] == "rllib" and "policy" not in rllib
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.seed = 1  # type: ignore[misc]
    with pytest.raises(ValueError, match="backend"):
        dataclasses.replace(config, backend="jax")
    with pytest.raises(ValueError, match="budget and n_envs"):
        TrainConfig.resolve(REVERSE, "ppo", 2, 0, hp, timesteps=0)


def test_run_folder_refuses_another_run_unless_overwrite(tmp_path: Path) -> None:
    assert default_run_dir(REVERSE, "sac", 3, 4) == Path("runs/reverse_n3_sac_s4")
    run = tmp_path / "run"
    assert choose_run_dir(tmp_path / "default", run) == run
    run.mkdir()
    write_config(run, ModelCard(seed=0))
    (run / "checkpoints").mkdir()
    (run / "notes.txt").write_text("kept")
    with pytest.raises(RunFolderError, match="already holds a run"):
        choose_run_dir(tmp_path / "default", run)
    assert choose_run_dir(tmp_path / "default", run, overwrite=True) == run
    assert sorted(path.name for path in run.iterdir()) == ["notes.txt"]
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    with pytest.raises(RunFolderError, match="is not a folder"):
        choose_run_dir(a_file)


def test_the_agents_read_the_scene_table() -> None:
    for env_id in ENV_IDS:
        core = core_class_of(env_id)
        assert curve_metric(env_id) == core.headline_metric
        assert default_baselines(env_id) == list(core.baselines)
        assert scene_of(env_id).split("_v")[0] == core.scene.lower()
        assert f"trailer_env/{scene_title(env_id)}" == env_id
    assert curve_metric(REVERSE) == "safe_rate"
    assert curve_metric("trailer_env/Heading-v0") == "success_rate"
    assert default_baselines("trailer_env/Heading-v0")[-1] == "heading-p"
    assert model_stem("ppo", REVERSE, 2) == "ppo_reverse_n2"
    with pytest.raises(ValueError, match="heading-p baseline is for trailer_env/Heading-v0"):
        make_baseline("heading-p", env_settings({"action_mode": "servo"}), REVERSE)


def test_report_scenarios_come_from_the_committed_cards(tmp_path: Path) -> None:
    from agents.evaluation.report import SCENARIOS, committed_scenarios

    assert SCENARIOS == (
        (REVERSE, 1),
        (REVERSE, 2),
        (REVERSE, 3),
        ("trailer_env/Reverse-v1", 1),
        ("trailer_env/Reverse-v1", 2),
        ("trailer_env/Reverse-v1", 3),
        ("trailer_env/Reverse-v1", 4),
        ("trailer_env/Reverse-v1", 5),
        ("trailer_env/Reverse-v1", 6),
        ("trailer_env/Coast-v0", 1),
        ("trailer_env/Coast-v0", 2),
        ("trailer_env/Heading-v0", 2),
        ("trailer_env/Dock-v0", 1),
        ("trailer_env/Dock-v0", 2),
    )
    for stem, env_id, n in (("b", "trailer_env/Dock-v0", 1), ("a", REVERSE, 4), ("c", "x", 1)):
        (tmp_path / f"{stem}.zip").write_bytes(b"")
        (tmp_path / f"{stem}.json").write_text(
            json.dumps({"env_id": env_id, "env_kwargs": {"n_trailers": n}})
        )
    assert committed_scenarios(tmp_path) == ((REVERSE, 4), ("trailer_env/Dock-v0", 1))


def test_run_and_model_names_carry_the_version_past_zero() -> None:
    from agents.envs import scene_of

    assert scene_of("trailer_env/Reverse-v0") == "reverse"
    assert scene_of("trailer_env/Reverse-v1") == "reverse_v1"
    assert scene_of("trailer_env/Dock-v0") == "dock"
