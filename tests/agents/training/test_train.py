"""Training through the CLI: a smoke run that beats random, checkpoints, and resuming."""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import pytest

from agents.artifacts.curves import read_curve
from agents.artifacts.run_folder import export_model, kept_model
from agents.commands import train
from agents.envs import env_settings
from agents.evaluation.metrics import rollout, summarize
from agents.policies.baselines import make_baseline
from agents.policies.registry import load_policy
from agents.policies.sb3 import load_model
from tests.agents.helpers import Touch

REVERSE = "trailer_env/Reverse-v0"


#: A small PPO for tests (rl-zoo3 format): 16 environments, 1024 steps per update.
SMALL_PPO = """\
trailer_env/Reverse-v0:
  n_envs: 16
  n_timesteps: 40000
  policy: MlpPolicy
  normalize: "dict(norm_obs=True, norm_reward=False)"
  n_steps: 64
  batch_size: 256
  n_epochs: 4
  learning_rate: !!float 1e-3
  gamma: 0.99
  policy_kwargs: "dict(net_arch=[32, 32], log_std_init=-1.0)"
  env_kwargs:
    n_trailers: 1
"""

SMALL_SAC = """\
trailer_env/Reverse-v0:
  n_envs: 2
  n_timesteps: 600
  policy: MlpPolicy
  buffer_size: 5000
  learning_starts: 100
  batch_size: 32
  policy_kwargs: "dict(net_arch=[16])"
"""


def _hyperparams(tmp_path: Path) -> Path:
    folder = tmp_path / "hyperparams"
    folder.mkdir()
    (folder / "ppo.yml").write_text(SMALL_PPO)
    (folder / "sac.yml").write_text(SMALL_SAC)
    return folder


def _train(tmp_path: Path, *extra: str, algo: str = "ppo") -> int:
    return train.main(
        [
            "--env",
            REVERSE,
            "--algo",
            algo,
            "--n-trailers",
            "1",
            "--seed",
            "0",
            "--hyperparams",
            str(tmp_path / "hyperparams"),
            "--no-progress",
            "--quiet",
            "--eval-episodes",
            "10",
            *extra,
        ]
    )


def test_smoke_training_beats_random(tmp_path: Path) -> None:
    """40k steps of PPO (a few seconds) keep one trailer from folding about twice as long.

    Measured with seeds 0, 1, 2: mean return 98, 119, 124 against random's 45 on the
    same 50 episodes (the zero action: 48).
    """
    _hyperparams(tmp_path)
    run = tmp_path / "run"
    assert _train(tmp_path, "--timesteps", "40000", "--run-dir", str(run)) == 0
    kwargs = {"n_trailers": 1}
    trained = summarize(
        rollout(
            load_policy(str(run / "final_model.zip"), REVERSE, kwargs), REVERSE, 50, 1000, kwargs
        )
    )
    random = summarize(
        rollout(
            make_baseline("random", env_settings(kwargs), REVERSE, 0), REVERSE, 50, 1000, kwargs
        )
    )
    assert 30.0 < random["mean_return"] < 60.0  # 44.7 when measured
    assert trained["mean_return"] > 1.8 * random["mean_return"]
    assert trained["failure_rate"] <= random["failure_rate"]  # folds and stops alike
    curve = read_curve(run / "evaluations.csv")
    assert curve[0]["timesteps"] == 0 and curve[-1]["timesteps"] == 40960
    card = json.loads((run / "best_model.json").read_text())
    assert card["algo"] == "ppo" and card["env_kwargs"] == {"n_trailers": 1}
    assert card["seed"] == 0 and card["timesteps"] == 40960 and card["wall_time_s"] > 0
    # The host's speed, measured when the run started, stands beside its wall time.
    assert card["host"]["benchmark"] == "reverse_v1_n3_batch8_ppo2048"
    assert card["host"]["env_steps_per_s"] > 0 and card["host"]["torch_threads"] == 1
    assert (run / "best_model_vecnormalize.json").is_file()


def test_shaped_training_records_its_potential_and_reports_unshaped_returns(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _hyperparams(tmp_path)
    run = tmp_path / "run"
    assert _train(tmp_path, "--timesteps", "2048", "--run-dir", str(run), "--shaping", "lqr") == 0
    card = json.loads((run / "final_model.json").read_text())
    assert card["shaping"] == {"potential": "lqr"}
    assert "--shaping" in card["command"]
    # The validation curve scores the scene's own reward and success, not the shaped one.
    first = read_curve(run / "evaluations.csv")[0]
    assert 30.0 < first["mean_return"] < 60.0  # the untrained policy, as without shaping
    with pytest.raises(SystemExit) as refused:
        _train(tmp_path, "--timesteps", "2048", "--shaping", "energy")
    assert refused.value.code == 2
    assert "--shaping: shaping needs a potential among ['lqr']" in capsys.readouterr().err
    with pytest.raises(SystemExit) as refused:
        _train(tmp_path, "--backend", "rllib", "--shaping", "lqr")
    assert refused.value.code == 2
    assert "--shaping: not supported with --backend rllib" in capsys.readouterr().err
    with pytest.raises(SystemExit) as refused:
        _train(tmp_path, "--backend", "rllib", "--export-model", "final")
    assert refused.value.code == 2
    assert "--export-model: not supported with --backend rllib" in capsys.readouterr().err


def test_resume_continues_the_timestep_count(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _hyperparams(tmp_path)
    run = tmp_path / "run"
    common = ["--run-dir", str(run), "--checkpoint-freq", "2048", "--eval-freq", "2048"]
    assert _train(tmp_path, "--timesteps", "4096", *common) == 0
    checkpoint = run / "checkpoints" / "ppo_2048_steps.zip"
    assert (
        checkpoint.is_file()
        and (run / "checkpoints" / "ppo_vecnormalize_2048_steps.json").is_file()
    )
    assert load_model(run / "final_model.zip").num_timesteps == 4096
    resumed = ["--resume", str(checkpoint), "--eval-freq", "2048"]
    # Statistics only in the legacy pickle format are not unpickled without the flag.
    stats = run / "checkpoints" / "ppo_vecnormalize_2048_steps.json"
    saved = stats.read_text()
    stats.unlink()
    marker = tmp_path / "ran"
    stats.with_suffix(".pkl").write_bytes(pickle.dumps(Touch(marker)))
    with pytest.raises(SystemExit) as refused:
        _train(tmp_path, "--timesteps", "6144", *resumed)
    assert refused.value.code == 2 and not marker.exists()
    assert "ppo_vecnormalize_2048_steps.pkl are a pickle" in capsys.readouterr().err
    stats.with_suffix(".pkl").unlink()
    stats.write_text(saved)
    assert _train(tmp_path, "--timesteps", "6144", *resumed) == 0
    assert load_model(run / "final_model.zip").num_timesteps == 6144
    steps = [int(row["timesteps"]) for row in read_curve(run / "evaluations.csv")]
    # The evaluation at 4096 before the resume belonged to the abandoned continuation.
    assert steps == [0, 2048, 4096, 6144]
    walls = [row["wall_s"] for row in read_curve(run / "evaluations.csv")]
    assert walls == sorted(walls)  # the wall clock goes on across the resume


def test_resume_and_init_from_read_the_files_env_kwargs(tmp_path: Path) -> None:
    # A file whose env_kwargs change the observation (observe_params: 7 more numbers):
    # the checkpoint is checked against that env, not the bare scene's.
    folder = _hyperparams(tmp_path)
    (folder / "ppo.yml").write_text(SMALL_PPO + "    observe_params: true\n")
    run = tmp_path / "run"
    common = ["--run-dir", str(run), "--checkpoint-freq", "2048", "--eval-freq", "2048"]
    assert _train(tmp_path, "--timesteps", "2048", *common) == 0
    assert load_model(run / "final_model.zip").observation_space.shape == (13,)
    resumed = ["--resume", str(run / "final_model.zip"), "--eval-freq", "2048"]
    assert _train(tmp_path, "--timesteps", "4096", *resumed) == 0
    assert load_model(run / "final_model.zip").num_timesteps == 4096
    tuned = ["--init-from", str(run / "final_model.zip"), "--run-dir", str(tmp_path / "tuned")]
    export = ["--export", str(tmp_path / "tuned.zip"), "--export-model", "final"]
    assert _train(tmp_path, "--timesteps", "2048", *tuned, *export) == 0
    # The exported model is the run's final one, and its recipe says so.
    assert (tmp_path / "tuned.zip").read_bytes() == (
        tmp_path / "tuned/final_model.zip"
    ).read_bytes()
    card = json.loads((tmp_path / "tuned.json").read_text())
    command = card["command"]
    # It was evaluated at its last step, not kept there: that row is its validation.
    assert card["validation"]["timesteps"] == card["timesteps"] == 2048
    assert "selected_at_timesteps" not in card
    assert command[command.index("--export-model") :][:2] == ["--export-model", "final"]


def test_off_policy_resume_restores_the_replay_buffer(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _hyperparams(tmp_path)
    run = tmp_path / "sac"
    common = ["--run-dir", str(run), "--checkpoint-freq", "300", "--eval-freq", "300"]
    assert _train(tmp_path, "--timesteps", "300", *common, algo="sac") == 0
    checkpoint = run / "checkpoints" / "sac_300_steps.zip"
    assert (run / "checkpoints" / "sac_replay_buffer_300_steps.pkl").is_file()
    # SB3 pickles the replay buffer: resuming with it is an explicit opt-in.
    resume = ["--timesteps", "400", "--resume", str(checkpoint), "--run-dir", str(run)]
    with pytest.raises(SystemExit) as refused:
        _train(tmp_path, *resume, algo="sac")
    assert refused.value.code == 2
    assert "replay buffer" in capsys.readouterr().err
    assert _train(tmp_path, *resume, "--trust-pickle", algo="sac") == 0
    model = load_model(run / "final_model.zip")
    assert model.num_timesteps == 400
    export = tmp_path / "models" / "sac_reverse_n1.zip"
    export_model(run, export)
    assert export.is_file() and export.with_suffix(".json").is_file()
    # The exported card's command is the recipe, not where the run's files went.
    exported = json.loads(export.with_suffix(".json").read_text())["command"]
    recorded = json.loads((run / "best_model.json").read_text())["command"]
    assert recorded[recorded.index("--run-dir") + 1] == str(run)
    assert exported == [item for item in recorded if item not in ("--run-dir", str(run))]
    assert export.with_suffix(".csv").is_file()
    # --export-model final copies the model at the end of the budget, the card it had.
    final = tmp_path / "models" / "sac_reverse_n1_final.zip"
    export_model(run, final, model="final")
    assert final.read_bytes() == (run / "final_model.zip").read_bytes()
    assert json.loads(final.with_suffix(".json").read_text())["timesteps"] == 400
    with pytest.raises(ValueError, match="model must be one of \\['best', 'final'\\]"):
        export_model(run, tmp_path / "models" / "other.zip", model="last")
    assert not (tmp_path / "models" / "other.zip").exists()


def test_the_kept_model_is_the_best_unless_the_command_keeps_the_final() -> None:
    assert kept_model(["--timesteps", "400"]) == "best_model.zip"
    assert kept_model(["--export-model", "final", "--seed", "0"]) == "final_model.zip"
    assert kept_model(["--export-model", "best"]) == "best_model.zip"
    assert kept_model(["--seed", "0", "--export-model"]) == "best_model.zip"


def test_a_generalist_trains_on_a_range_of_counts_and_randomised_physics(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    _hyperparams(tmp_path)
    monkeypatch.chdir(tmp_path)
    extra = ("--timesteps", "2048", "--n-trailers", "1-3", "--randomize", "mismatch20")
    assert _train(tmp_path, *extra) == 0
    run = tmp_path / "runs" / "reverse_n1-3_ppo_s0"  # the default folder names the range
    card = json.loads((run / "final_model.json").read_text())
    assert card["env_kwargs"] == {"n_trailers": [1, 3], "randomize": "mismatch20"}
    assert "--randomize" in card["command"]
    # The padded model acts on each n of its range through agents.evaluate's loader.
    for n in (1, 3):
        summary = summarize(rollout(load_policy(str(run / "final_model.zip"), REVERSE,
                                                {"n_trailers": n}), REVERSE, 4, 1000,
                                    {"n_trailers": n}))  # fmt: skip
        assert summary["episodes"] == 4
    for bad, message in (
        (("--n-trailers", "3-1"), "a range LOW-HIGH needs 0 <= LOW < HIGH"),
        (("--n-trailers", "1-9"), "n_trailers = (1, 9)"),
        (("--randomize", "mismatch50"), "invalid choice: 'mismatch50'"),
        (("--n-trailers", "1-3", "--shaping", "lqr"), "--shaping: shaping (--shaping or the"),
    ):
        with pytest.raises(SystemExit) as refused:
            _train(tmp_path, "--timesteps", "2048", "--run-dir", str(tmp_path / "r2"), *bad)
        assert refused.value.code == 2
        assert message in capsys.readouterr().err
        assert not (tmp_path / "r2").exists()


def test_the_best_model_loads_while_the_run_goes_on(tmp_path: Path) -> None:
    """The best model's card names its env, n and algorithm from its first save, so that
    a padded generalist's kept model evaluates mid-run (the card was the validation row
    alone until the run ended)."""
    from agents.training.config import TrainConfig, load_hyperparams
    from agents.training.sb3 import train as train_sb3

    folder = _hyperparams(tmp_path)
    hp = load_hyperparams("ppo", REVERSE, folder)
    config = TrainConfig.resolve(REVERSE, "ppo", (1, 2), 0, hp, timesteps=2048)
    run = tmp_path / "run"
    seen: list[dict[str, object]] = []

    def peek(steps: int, row: object) -> bool:
        seen.append(json.loads((run / "best_model.json").read_text()))
        summary = summarize(rollout(load_policy(str(run / "best_model.zip"), REVERSE,
                                                {"n_trailers": 2}), REVERSE, 2, 1000,
                                    {"n_trailers": 2}))  # fmt: skip
        assert summary["episodes"] == 2
        return False

    train_sb3(config, run, eval_freq=1024, eval_episodes=2, progress_bar=False, verbose=0,
              hooks=[peek])  # fmt: skip
    assert [card["selected_at_timesteps"] for card in seen][:1] == [0]
    assert all(card["env_kwargs"] == {"n_trailers": [1, 2]} for card in seen)
    assert all(card["algo"] == "ppo" and "timesteps" not in card for card in seen)
