"""``python -m agents.select``: the training seed committed is the best on the selection
episodes, played in the env its card records (physics and memory window)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents.commands import select, train
from agents.evaluation.metrics import rollout, summarize
from agents.evaluation.selection import SELECTION_EPISODES
from agents.policies.registry import load_policy
from agents.seeds import SELECTION_SEED
from tests.agents.helpers import refusal, tiny_ppo_hyperparams

REVERSE = "trailer_env/Reverse-v1"
#: What the tiny runs train in: randomised physics and a memory of two frames.
KWARGS: dict[str, object] = {"n_trailers": 1, "randomize": "mismatch20", "history": 2}


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two tiny PPO runs (training seeds 0 and 1) under mismatch20 with a 2-frame window,
    one (seed 3) over n = 1-2 likewise, and one (seed 2) under nominal physics."""
    root = tmp_path_factory.mktemp("select")
    hp = tiny_ppo_hyperparams(root / "hp", REVERSE)
    hp.write_text(hp.read_text() + "  env_kwargs:\n    history: 2\n")
    for seed in (0, 1):
        argv = ["--env", REVERSE, "--algo", "ppo", "--n-trailers", "1"]
        argv += ["--randomize", "mismatch20", "--hyperparams", str(root / "hp")]
        argv += ["--run-dir", str(root / f"runs/s{seed}"), "--timesteps", "1024"]
        argv += ["--eval-freq", "512", "--eval-episodes", "2", "--seed", str(seed)]
        assert train.main([*argv, "--no-progress", "--quiet"]) == 0
    both = ["--env", REVERSE, "--algo", "ppo", "--n-trailers", "1-2", "--randomize"]
    both += ["mismatch20", "--hyperparams", str(root / "hp"), "--run-dir", str(root / "both")]
    both += ["--timesteps", "512", "--eval-freq", "512", "--eval-episodes", "2", "--seed", "3"]
    assert train.main([*both, "--no-progress", "--quiet"]) == 0
    nominal = ["--env", REVERSE, "--algo", "ppo", "--n-trailers", "1", "--hyperparams"]
    nominal += [str(root / "hp"), "--run-dir", str(root / "nominal"), "--timesteps", "512"]
    nominal += ["--eval-freq", "512", "--eval-episodes", "2", "--seed", "2"]
    assert train.main([*nominal, "--no-progress", "--quiet"]) == 0
    return root


def _selection_rate(model: Path, n: int = 1) -> float:
    kwargs = {**KWARGS, "n_trailers": n}
    policy = load_policy(str(model), REVERSE, kwargs, seed=SELECTION_SEED)
    played = rollout(policy, REVERSE, SELECTION_EPISODES, SELECTION_SEED, kwargs)
    return float(summarize(played)["safe_rate"])


def test_the_best_seed_under_the_cards_physics_is_exported(runs: Path, tmp_path: Path) -> None:
    model = tmp_path / "models" / "tiny.zip"
    folders = [str(runs / "runs" / "s1"), str(runs / "runs" / "s0")]
    assert select.main([*folders, "--export", str(model)]) == 0
    card = json.loads(model.with_suffix(".json").read_text())
    expected = {str(s): _selection_rate(runs / f"runs/s{s}/best_model.zip") for s in (0, 1)}
    assert card["selection"]["safe_rate_per_training_seed"] == expected
    best = max(sorted(expected), key=lambda seed: expected[seed])  # ties to the lower seed
    assert card["seed"] == card["selection"]["chosen_seed"] == int(best)
    assert card["selection"]["seeds"] == [SELECTION_SEED, SELECTION_SEED + SELECTION_EPISODES - 1]
    assert card["env_kwargs"] == KWARGS
    # The recipe without where the run's files went (a reproduction sets that).
    run_dir = json.loads((runs / f"runs/s{best}/best_model.json").read_text())["command"]
    assert "--run-dir" in run_dir and "--run-dir" not in card["command"]
    assert card["command"] == [
        item for item in run_dir if "runs/s" not in item and item != "--run-dir"
    ]
    siblings = sorted(p.name for p in (tmp_path / "models" / "seeds").glob("*.zip"))
    assert siblings == ["tiny_s0.zip", "tiny_s1.zip"]
    chosen = (runs / f"runs/s{best}/best_model.zip").read_bytes()
    assert model.read_bytes() == chosen


def test_one_policy_for_a_range_of_n_is_chosen_on_its_mean_over_the_counts(
    runs: Path, tmp_path: Path
) -> None:
    model = tmp_path / "models" / "both.zip"
    assert select.main([str(runs / "both"), "--export", str(model)]) == 0
    card = json.loads(model.with_suffix(".json").read_text())
    assert card["env_kwargs"]["n_trailers"] == [1, 2]
    kept = runs / "both" / "best_model.zip"
    mean = (_selection_rate(kept, 1) + _selection_rate(kept, 2)) / 2
    assert card["selection"]["safe_rate_per_training_seed"] == {"3": pytest.approx(mean)}
    assert card["selection"]["chosen_seed"] == card["seed"] == 3


def test_refusals_write_nothing(
    runs: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    s0, s1 = str(runs / "runs" / "s0"), str(runs / "runs" / "s1")
    model = tmp_path / "models" / "tiny.zip"
    export = ["--export", str(model)]

    def refused(*argv: str) -> str:
        return refusal(select.main, list(argv), capsys)

    assert "both training seed 0" in refused(s0, s0, *export)
    assert "has no best_model.zip" in refused(s0, str(tmp_path), *export)
    assert "different scenes, n, physics" in refused(s0, str(runs / "nominal"), *export)
    assert "must name a .zip" in refused(s0, s1, "--export", str(tmp_path / "m.pt"))
    assert not (tmp_path / "models").exists()
    model.parent.mkdir()
    model.write_bytes(b"kept")
    assert "pass --overwrite" in refusal(select.main, [s0, s1, "--export", str(model)], capsys)
    assert model.read_bytes() == b"kept" and not (tmp_path / "models" / "seeds").exists()
