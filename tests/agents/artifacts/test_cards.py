"""Model cards: every committed card read and written back unchanged; bad cards refused
with the field named; a model without a card reads as the empty card."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents.algorithms.options import StartCurriculum, StartReplay
from agents.artifacts.cards import (
    EnvKwargs,
    ModelCard,
    Spaces,
    card_of,
    read_model_card,
    write_card,
)
from agents.artifacts.records import SCHEMA_KEY, DocumentError
from agents.artifacts.rllib_files import POLICY_CARD, read_rllib_card
from agents.artifacts.run_folder import read_run_record, write_config
from agents.artifacts.shipped import MODELS_DIR

CARDS = sorted(
    path for path in MODELS_DIR.glob("**/*.json") if not path.name.endswith("_vecnormalize.json")
)


def test_every_committed_card_reads_and_writes_back_the_same_document() -> None:
    assert len(CARDS) == 97
    for path in CARDS:
        document = json.loads(path.read_text())
        card = ModelCard.from_json(document, str(path))
        assert card.to_json() == {SCHEMA_KEY: ModelCard.SCHEMA_VERSION, **document}
        assert card.algo in ("ppo", "sac") and card.env_id is not None
        assert card.validation is not None and card.timesteps is not None


def test_committed_cards_read_by_attribute() -> None:
    generalist = read_model_card(MODELS_DIR / "dagger_reverse_v1_general.zip")
    assert generalist.env_kwargs.is_range and generalist.n_trailers == (1, 3)
    assert generalist.imitation is not None and generalist.planner is not None
    assert generalist.recipe == "dagger" and generalist.normalize is not None
    mirrored = [
        path for path in CARDS if ModelCard.from_json(json.loads(path.read_text())).mirrored
    ]
    assert len(mirrored) == 8
    selected = [
        card
        for card in (ModelCard.from_json(json.loads(path.read_text())) for path in CARDS)
        if card.selection is not None
    ]
    assert len(selected) == 14
    for card in selected:
        assert card.selection is not None
        assert str(card.selection.chosen_seed) in card.selection.rates


def test_a_model_without_a_card_reads_as_the_empty_card(tmp_path: Path) -> None:
    card = read_model_card(tmp_path / "m.zip")
    assert card.empty and card == ModelCard() and card.env_kwargs == EnvKwargs()
    assert not card.mirrored and card.n_trailers is None


@pytest.mark.parametrize(
    ("document", "named"),
    [
        ({"algo": 3}, "'algo'"),
        ({"colour": "red"}, "'colour'"),
        ({"env_kwargs": {"n_trailers": [3, 1]}}, "n_trailers"),
        ({"env_kwargs": {"n_trailers": True}}, "n_trailers"),
        ({"imitation": {"iterations": 1}}, "imitation"),
        ({"validation": {"safe_rate": "high"}}, "'safe_rate'"),
        ({"normalize": {"norm_obs": True, "norm_reward": 1}}, "'norm_reward'"),
        ({"wall_time_s": float("inf")}, "wall_time_s"),
        ({SCHEMA_KEY: 99}, SCHEMA_KEY),
        ([1, 2], "JSON object"),
    ],
)
def test_a_bad_card_is_refused_naming_the_field(
    tmp_path: Path, document: object, named: str
) -> None:
    path = tmp_path / "m.json"
    path.write_text(json.dumps(document))
    with pytest.raises(DocumentError, match=named):
        read_model_card(path.with_suffix(".zip"))


def test_env_kwargs_keep_the_keywords_they_do_not_name() -> None:
    kwargs = {"n_trailers": 2, "mu": 0.4, "dt": 0.1, "randomize": "mismatch20"}
    card = ModelCard.from_json({"env_kwargs": kwargs})
    assert card.env_kwargs.other == {"mu": 0.4, "dt": 0.1}
    assert card.env_kwargs.randomize == "mismatch20" and card.n_trailers == 2
    assert card.env_kwargs.as_kwargs() == kwargs


def test_the_start_curriculum_keeps_its_from_key() -> None:
    card = ModelCard.from_json({"start_curriculum": {"from": 0.25, "steps": 1000}})
    assert card.option(StartCurriculum) == StartCurriculum(0.25, 1000)
    assert card.to_json()["start_curriculum"] == {"from": 0.25, "steps": 1000}


def test_write_card_writes_a_card_and_refuses_anything_else(tmp_path: Path) -> None:
    model = tmp_path / "m.zip"
    card = ModelCard(algo="ppo", env_id="Reverse-v0", seed=3, timesteps=100)
    write_card(model, card)
    assert read_model_card(model) == card
    document = {"algo": "sac", "env_id": "Coast-v0", "seed": 1, "env_kwargs": {}}
    with pytest.raises(TypeError, match="write_card takes a ModelCard, got dict"):
        write_card(model, document)  # type: ignore[arg-type]
    assert read_model_card(model) == card  # the refused card wrote nothing
    write_card(model, card_of(document, "of m"))
    assert read_model_card(model).algo == "sac"
    with pytest.raises(DocumentError, match="model card of m: 'budget'"):
        card_of({"budget": "lots"}, "of m")
    assert card_of({"env_kwargs": {"n_trailers": (1, 3)}}, "of m").n_trailers == (1, 3)


def test_a_run_record_is_checked_when_written_and_read(tmp_path: Path) -> None:
    record = {"algo": "ppo", "env_id": "trailer_env/Reverse-v0", "env_kwargs": {}, "seed": 0}
    write_config(tmp_path, card_of({**record, "start_replay": {"fraction": 0.25}}, "of m"))
    card = read_run_record(tmp_path)
    assert card.option(StartReplay) == StartReplay(0.25) and card.seed == 0
    with pytest.raises(DocumentError, match=r"of m: start_replay.fraction must be a number"):
        card_of({**record, "start_replay": {"fraction": "a quarter"}}, "of m")
    with pytest.raises(TypeError, match="write_config takes a ModelCard, got dict"):
        write_config(tmp_path, {**record, "seed": 1})  # type: ignore[arg-type]
    assert read_run_record(tmp_path) == card  # the refused record wrote nothing
    (tmp_path / "config.json").write_text(json.dumps({**record, "sed": 1}))
    with pytest.raises(ValueError, match=r"run record .*unknown field 'sed'"):
        read_run_record(tmp_path)
    (tmp_path / "config.json").write_text(json.dumps({"algo": "ppo"}))
    with pytest.raises(ValueError, match="lacks 'env_id', 'env_kwargs', 'seed'"):
        read_run_record(tmp_path)


def test_an_rllib_policy_card_reads_its_spaces_and_network(tmp_path: Path) -> None:
    spaces = {
        "observation_shape": [6],
        "action_shape": [1],
        "action_low": [-1.0],
        "action_high": [1.0],
    }
    document = {
        "algo": "ppo",
        "backend": "rllib",
        "env_id": "trailer_env/Reverse-v0",
        "env_kwargs": {"n_trailers": 1},
        "seed": 0,
        "hyperparams": {"fcnet_hiddens": [32, 32]},
        "runner_envs": [["ConvoyVectorEnv", True, "node"]],
        "module_path": "ray.rllib.algorithms.ppo.torch.default_ppo_torch_rl_module:X",
        "inference_only": True,
        "spaces": spaces,
    }
    (tmp_path / POLICY_CARD).write_text(json.dumps(document))
    card = read_rllib_card(tmp_path)
    assert card.spaces == Spaces((6,), (1,), (-1.0,), (1.0,)) and card.rllib_hiddens == [32, 32]
    assert read_rllib_card(tmp_path / "none").empty
    (tmp_path / POLICY_CARD).write_text(
        json.dumps({**document, "hyperparams": {"fcnet_hiddens": [0]}})
    )
    with pytest.raises(ValueError, match="net_arch"):
        read_rllib_card(tmp_path)
