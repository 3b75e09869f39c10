"""The training options as records: one table, each parsed, checked, recorded, read back
and tagged by itself; the recipe's name from the table of tags and the options."""

from __future__ import annotations

import argparse
import re
from dataclasses import dataclass

import pytest

from agents.algorithms.options import (
    TRAINING_OPTIONS,
    FineTune,
    OptionError,
    Shaping,
    StartCurriculum,
    StartReplay,
    recorded_options,
)
from agents.algorithms.recipes import RECIPE_TAGS, recipe_name

V1 = "trailer_env/Reverse-v1"


@dataclass(frozen=True)
class Run:
    """The run an option is checked against (what TrainConfig gives)."""

    env_id: str = V1
    algo: str = "ppo"
    backend: str = "sb3"
    budget: int = 4096
    n_trailers: int | tuple[int, int] = 2
    randomize: str | None = None

    @property
    def env_kwargs(self) -> dict[str, object]:
        physics = {} if self.randomize is None else {"randomize": self.randomize}
        return {"n_trailers": self.n_trailers, **physics}


def _args(**given: object) -> argparse.Namespace:
    flags = {flag.dest: flag.default for kind in TRAINING_OPTIONS for flag in kind.FLAGS}
    return argparse.Namespace(**{**flags, **given})


def test_the_table_orders_the_tags_and_names_every_flag_once() -> None:
    assert (Shaping, StartCurriculum, StartReplay, FineTune) == TRAINING_OPTIONS
    flags = [flag.name for kind in TRAINING_OPTIONS for flag in kind.FLAGS]
    assert flags == [
        "--shaping",
        "--start-curriculum",
        "--start-replay",
        "--start-replay-max",
        "--init-from",
        "--critic-warmup",
    ]
    keys = [key for kind in TRAINING_OPTIONS for key in kind.KEYS]
    assert keys == ["shaping", "start_curriculum", "start_replay", "init_from", "critic_warmup"]


@pytest.mark.parametrize(
    ("option", "part", "tag", "flags"),
    [
        (Shaping("lqr"), {"shaping": {"potential": "lqr"}}, " + lqr shaping", "--shaping lqr"),
        (
            Shaping("lqr", 1, -0.5),
            {"shaping": {"potential": "lqr", "scale": 1, "reference": -0.5}},
            " + lqr shaping",
            "--shaping \"dict(potential='lqr', scale=1, reference=-0.5)\"",
        ),
        (
            StartCurriculum(0.2, 2048),
            {"start_curriculum": {"from": 0.2, "steps": 2048}},
            " + start curriculum",
            "--start-curriculum 0.2,2048",
        ),
        (
            StartReplay(0.25, 2),
            {"start_replay": {"fraction": 0.25, "max_replays": 2}},
            " + start replay 0.25 (max 2)",
            "--start-replay 0.25 --start-replay-max 2",
        ),
        (
            StartReplay(0.5),
            {"start_replay": {"fraction": 0.5}},
            " + start replay 0.5",
            "--start-replay 0.5",
        ),
        (
            FineTune("runs/a/best_model.zip", 1024),
            {"init_from": "runs/a/best_model.zip", "critic_warmup": 1024},
            " from best_model",
            "--init-from runs/a/best_model.zip --critic-warmup 1024",
        ),
    ],
)
def test_each_option_writes_reads_back_and_names_itself(
    option: Shaping | StartCurriculum | StartReplay | FineTune,
    part: dict[str, object],
    tag: str,
    flags: str,
) -> None:
    assert option.record() == part
    assert type(option).from_record(part) == option
    assert type(option).from_record({}) is None
    assert recorded_options({"algo": "ppo", **part}) == (option,)
    assert option.tag() == tag and option.flags_text() == flags
    option.check(Run())  # a run each fits


def test_the_recipe_is_named_from_the_tags_then_the_options_in_table_order() -> None:
    record = {
        "algo": "ppo",
        "hyperparams": {"use_sde": True, "policy_kwargs": {"net_arch": [256, 256]}},
        "env_kwargs": {
            "n_trailers": 2,
            "randomize": "mismatch20",
            "trailer_draw": "row",
            "history": 8,
        },
        "shaping": {"potential": "lqr"},
        **FineTune("m/dagger_reverse_v1_n2.zip").record(),
        **StartReplay(0.25, 3).record(),
        **StartCurriculum(0.5, 100).record(),
    }
    assert recipe_name(record, upper=True) == (
        "PPO (gSDE, 256x256, mismatch20, n by row, history 8) + lqr shaping + start curriculum"
        " + start replay 0.25 (max 3) from dagger_reverse_v1_n2"
    )
    assert (
        recipe_name({"algo": "sac", "hyperparams": {"policy_kwargs": {"net_arch": [64, 64]}}})
        == "sac"
    )
    assert len(RECIPE_TAGS) == 5  # every tag goes in the parentheses; options follow them


@pytest.mark.parametrize(
    ("given", "flag", "words"),
    [
        ({"start_replay_max": 2}, "--start-replay-max", "needs start_replay"),
        ({"critic_warmup": 1024}, "--critic-warmup", "only with --init-from"),
        ({"start_curriculum": (1.5, 10)}, "--start-curriculum", "0 < low < 1"),
        ({"shaping": "energy"}, "--shaping", "shaping needs a potential among ['lqr']"),
        ({"shaping": "dict(potential='lqr', weight=2)"}, "--shaping", "shaping has no 'weight'"),
    ],
)
def test_values_that_do_not_go_together_are_refused_naming_the_flag(
    given: dict[str, object], flag: str, words: str
) -> None:
    refusals = []
    for kind in TRAINING_OPTIONS:
        try:
            kind.from_args(_args(**given))
        except OptionError as error:
            refusals.append((error.flag, str(error)))
    assert len(refusals) == 1 and refusals[0][0] == flag and words in refusals[0][1]


@pytest.mark.parametrize(
    ("option", "run", "flag", "words"),
    [
        (Shaping("lqr"), Run(backend="rllib"), "--shaping", "not supported with --backend rllib"),
        (Shaping("lqr"), Run(n_trailers=(1, 3)), "--shaping", "one count of trailers"),
        (StartReplay(0.5), Run(backend="rllib"), "--start-replay", "not supported"),
        (StartReplay(0.5), Run(n_trailers=(1, 3)), "--start-replay", "one count of trailers"),
        (
            StartCurriculum(0.2, 10),
            Run(env_id="trailer_env/Dock-v0"),
            "--start-curriculum",
            "no perturbation size",
        ),
        (FineTune("m.zip"), Run(algo="sac"), "--init-from", "sac is off-policy"),
        (
            FineTune("m.zip", 4096),
            Run(),
            "--critic-warmup",
            "critic_warmup (4096) must be under the budget (4096)",
        ),
    ],
)
def test_an_option_refuses_a_run_it_cannot_be_part_of(
    option: Shaping | StartReplay | StartCurriculum | FineTune, run: Run, flag: str, words: str
) -> None:
    with pytest.raises(OptionError, match=re.escape(words)) as refused:
        option.check(run)
    assert refused.value.flag == flag


def test_start_replay_takes_a_run_of_drawn_physics() -> None:
    StartReplay(0.5).check(Run(randomize="mismatch20"))  # the start keeps its drawn convoy


@pytest.mark.parametrize(
    ("record", "words"),
    [
        ({"start_replay": 0.5}, "start_replay must be an object"),
        ({"start_replay": {"fraction": 0.5, "max": 2}}, "start_replay has no field 'max'"),
        ({"start_replay": {"fraction": "half"}}, "start_replay.fraction must be a number"),
        (
            {"start_curriculum": {"from": 0.2, "steps": 1.5}},
            "start_curriculum.steps must be an integer",
        ),
        ({"init_from": 3}, "init_from must be a path"),
        ({"shaping": "lqr"}, "shaping must be an object"),
        ({"shaping": {"potential": 1}}, "shaping.potential must be a string"),
        ({"shaping": {"potential": "lqr", "scale": "big"}}, "shaping.scale must be a number"),
        ({"shaping": {"potential": "lqr", "weight": 2}}, "shaping has no field 'weight'"),
    ],
)
def test_a_malformed_recorded_option_is_refused_naming_its_key(
    record: dict[str, object], words: str
) -> None:
    with pytest.raises(ValueError, match=words):
        recorded_options(record)


def test_a_fine_tuning_run_goes_on_from_the_same_source_by_its_resolved_path() -> None:
    saved = FineTune("runs/../runs/a/best_model.zip", 1024)
    assert FineTune("runs/a/best_model.zip", 1024).same_run(saved)
    assert not FineTune("runs/a/best_model.zip", 0).same_run(saved)
    assert not StartReplay(0.5).same_run(StartReplay(0.5, 2))


def test_shaping_none_is_no_option_and_no_flag_given() -> None:
    assert Shaping.from_args(_args(shaping="none")) is None
    assert Shaping.from_args(_args()) is None
    assert not Shaping.given(_args(shaping="none")) and Shaping.given(_args(shaping="lqr"))
    parsed = Shaping.from_args(_args(shaping="dict(potential='lqr', scale=0.5)"))
    assert parsed == Shaping("lqr", 0.5)
    assert parsed.keywords() == {"potential": "lqr", "scale": 0.5}
