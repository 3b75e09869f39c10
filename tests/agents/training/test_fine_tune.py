"""Fine-tuning (`agents.train --init-from`): the start is the source's policy, its
statistics stay frozen, and the critic warm-up leaves the policy untouched."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from agents.algorithms.recipes import recipe_name
from agents.artifacts.curves import read_curve
from agents.artifacts.stats import read_stats
from agents.policies.sb3 import load_model
from tests.agents.training.test_train import REVERSE, _hyperparams, _train


def _policy_and_value(path: Path) -> tuple[dict[str, torch.Tensor], dict[str, torch.Tensor]]:
    state = load_model(
        path, "ppo", env_id=REVERSE, env_kwargs={"n_trailers": 1}
    ).policy.state_dict()
    value = {k: v for k, v in state.items() if "value" in k}
    policy = {k: v for k, v in state.items() if "value" not in k}
    return policy, value


@pytest.fixture
def source(tmp_path: Path) -> Path:
    """A briefly trained PPO model with its statistics: the model to fine-tune."""
    _hyperparams(tmp_path)
    run = tmp_path / "source"
    assert _train(tmp_path, "--timesteps", "2048", "--run-dir", str(run)) == 0
    return run / "final_model.zip"


def test_warm_up_trains_the_value_function_alone_then_the_policy(
    tmp_path: Path, source: Path
) -> None:
    run = tmp_path / "tuned"
    warm = ["--critic-warmup", "2048", "--checkpoint-freq", "1024", "--eval-freq", "1024"]
    args = ["--init-from", str(source), *warm, "--timesteps", "3072", "--run-dir", str(run)]
    assert _train(tmp_path, *args) == 0
    # Rollouts of 1024 steps: the checkpoint at 2048 has had one update (the warm-up's),
    # which moved the critic only.
    source_policy, source_value = _policy_and_value(source)
    tuned_policy, tuned_value = _policy_and_value(run / "checkpoints" / "ppo_2048_steps.zip")
    assert source_policy.keys() == tuned_policy.keys() and len(source_value) >= 2
    for key, weights in source_policy.items():
        assert torch.equal(weights, tuned_policy[key]), key
    assert any(not torch.equal(w, tuned_value[k]) for k, w in source_value.items())
    # Frozen statistics: the run's are the source's, exactly.
    source_stats = read_stats(source.with_name("final_model_vecnormalize.json"))
    tuned_stats = read_stats(run / "final_model_vecnormalize.json")
    assert source_stats.obs_rms == tuned_stats.obs_rms
    # The warm-up's evaluations (after 0, 1 and 2 updates) score the source's policy.
    curve = read_curve(run / "evaluations.csv")
    assert [row["timesteps"] for row in curve] == [0, 1024, 2048, 3072]
    assert len({(row["mean_return"], row["safe_rate"]) for row in curve[:3]}) == 1
    card = json.loads((run / "final_model.json").read_text())
    assert card["init_from"] == str(source) and card["critic_warmup"] == 2048
    # A recipe of its own in the tables and charts, named by its starting model.
    assert recipe_name(card) == "ppo (32x32) from final_model"
    # The third update, past the warm-up, moves the policy.
    moved, _ = _policy_and_value(run / "final_model.zip")
    assert any(not torch.equal(w, moved[k]) for k, w in source_policy.items())
    model = load_model(run / "final_model.zip")
    assert all(p.requires_grad for p in model.policy.parameters())  # saved trainable


def test_resuming_a_fine_tuning_run_needs_its_source(
    tmp_path: Path, source: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "tuned"
    warm = ["--critic-warmup", "1024", "--checkpoint-freq", "1024", "--eval-freq", "1024"]
    args = ["--init-from", str(source), *warm, "--timesteps", "2048", "--run-dir", str(run)]
    assert _train(tmp_path, *args) == 0
    checkpoint = run / "checkpoints" / "ppo_1024_steps.zip"
    before = {p: p.stat().st_mtime_ns for p in run.rglob("*") if p.is_file()}
    for extra in ([], ["--init-from", str(source)]):
        with pytest.raises(SystemExit) as refused:
            _train(tmp_path, "--resume", str(checkpoint), "--timesteps", "3072", *extra)
        assert refused.value.code == 2
        err = capsys.readouterr().err
        assert f"--init-from {source} --critic-warmup 1024; resume it with the same" in err
    assert before == {p: p.stat().st_mtime_ns for p in run.rglob("*") if p.is_file()}


def test_refusals_touch_nothing(
    tmp_path: Path, source: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "refused"
    cases = [
        (["--critic-warmup", "1024"], "--critic-warmup: only with --init-from"),
        (["--init-from", str(tmp_path / "missing.zip")], "--init-from: no model file"),
        (
            ["--init-from", str(source), "--critic-warmup", "99999"],
            "critic_warmup (99999) must be under the budget (4096)",
        ),
        (["--init-from", str(source), "--algo", "sac"], "--init-from: sac is off-policy"),
        (
            ["--init-from", str(source), "--backend", "rllib"],
            "--init-from: not supported with --backend rllib",
        ),
    ]
    for extra, message in cases:
        algo = "sac" if "sac" in extra else "ppo"
        args = [a for a in extra if a not in ("--algo", "sac")]
        with pytest.raises(SystemExit) as refused:
            _train(tmp_path, "--timesteps", "4096", "--run-dir", str(run), *args, algo=algo)
        assert refused.value.code == 2
        assert message in capsys.readouterr().err
        assert not run.exists()
    # The source in the run folder that --overwrite would clear.
    with pytest.raises(SystemExit):
        _train(tmp_path, "--init-from", str(source), "--run-dir", str(source.parent), "--overwrite")
    assert f"{source} lies in the run folder {source.parent}" in capsys.readouterr().err
    assert source.is_file() and (source.parent / "checkpoints").is_dir()
    # A model imitated with the mirror acts through it: its bare network is another policy.
    card = source.with_name("final_model.json")
    saved_card = card.read_text()
    imitation = {"iterations": 1, "episodes": 8, "epochs": 1, "batch_size": 64}
    imitation |= {"learning_rate": 1e-3, "validation_episodes": 8, "mirror": True}
    card.write_text(json.dumps({**json.loads(saved_card), "imitation": imitation}))
    with pytest.raises(SystemExit):
        _train(tmp_path, "--init-from", str(source), "--run-dir", str(run))
    assert "was trained with the mirror" in capsys.readouterr().err
    assert not run.exists()
    card.write_text(saved_card)
    stats = source.with_name("final_model_vecnormalize.json")
    stats.unlink()
    with pytest.raises(SystemExit):
        _train(tmp_path, "--init-from", str(source), "--run-dir", str(run))
    assert "has no observation statistics" in capsys.readouterr().err
    assert not run.exists()
