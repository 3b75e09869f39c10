"""`agents.train --start-replay`: the training env replays failed starts, the evaluations
do not, the record and recipe name it, and refusals touch nothing."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents.algorithms.options import StartReplay
from agents.algorithms.recipes import recipe_name
from agents.artifacts.curves import read_curve
from agents.training.config import TrainConfig, load_hyperparams
from agents.training.sb3 import train
from tests.agents.training.test_start_curriculum import (
    V1,
    _folder,
    assert_refused,
    assert_resume_keeps,
)


def test_a_run_with_start_replay_replays_and_records_it(tmp_path: Path) -> None:
    hp = load_hyperparams("ppo", V1, _folder(tmp_path, normalize=False))
    runs = {}
    for name, share in (("plain", None), ("replayed", 0.5)):
        options = () if share is None else (StartReplay(share),)
        config = TrainConfig.resolve(V1, "ppo", 1, 0, hp, timesteps=2048, options=options)
        runs[name] = train(
            config, tmp_path / name, eval_freq=2048, eval_episodes=8, progress_bar=False,
            verbose=0,
        )  # fmt: skip
    replay = runs["replayed"].get_env().unwrapped.start_replay  # type: ignore[attr-defined]
    assert replay.fraction == 0.5 and replay.seed == 0
    assert replay.replayed > 0  # a random policy folds: failed starts came back
    assert runs["plain"].get_env().unwrapped.start_replay is None  # type: ignore[attr-defined]
    # The step-0 evaluation (same seed, same initial policy) is the scene's, unchanged.
    first = [read_curve(tmp_path / name / "evaluations.csv")[0] for name in runs]
    assert first[0] == {**first[1], "wall_s": first[0]["wall_s"]}
    card = json.loads((tmp_path / "replayed" / "final_model.json").read_text())
    assert card["start_replay"] == {"fraction": 0.5}
    assert recipe_name(card) == "ppo (32x32) + start replay 0.5"
    progress = (tmp_path / "replayed" / "logs" / "from_0" / "progress.csv").read_text()
    assert "start_replay/buffer" in progress.splitlines()[0]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--start-replay", "0"], "expected a number in (0, 1)"),
        (["--start-replay", "1"], "expected a number in (0, 1)"),
        (["--start-replay", "half"], "expected a number in (0, 1)"),
        (["--start-replay", "0.5", "--backend", "rllib"], "not supported"),
        (["--start-replay", "0.5", "--n-trailers", "1-2"], "one count of trailers"),
        (["--start-replay-max", "2"], "needs start_replay"),
        (["--start-replay", "0.5", "--start-replay-max", "0"], "must be >= 1"),
    ],
)
def test_refusals_touch_nothing(
    tmp_path: Path, extra: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert_refused(tmp_path, extra, message, capsys)


def test_a_resume_keeps_the_runs_start_replay(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    option = ["--start-replay", "0.25", "--start-replay-max", "2"]
    others = [[], ["--start-replay", "0.5"], ["--start-replay", "0.25"]]
    words = "trained with --start-replay 0.25 --start-replay-max 2; resume it"
    run = assert_resume_keeps(tmp_path, capsys, option, others, words)
    card = json.loads((run / "final_model.json").read_text())
    assert card["start_replay"] == {"fraction": 0.25, "max_replays": 2}
    assert recipe_name(card) == "ppo (32x32) + start replay 0.25 (max 2)"
