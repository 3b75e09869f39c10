"""DAgger from the planner: the run folder, a model that loads like any PPO model, bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from agents.artifacts.curves import read_curve
from agents.commands.imitate import main
from agents.envs import env_settings
from agents.oracles.planner import PlannerConfig, SamplingPlanner
from agents.policies.registry import load_policy
from agents.training.dagger import collect
from agents.training.imitate import imitate
from agents.training.imitation_config import MAX_VALIDATION_EPISODES, ImitationConfig
from trailer_env.scenes.reverse_v1 import ReverseV1Core
from trailer_env.vector import ConvoyVectorEnv

V1 = "trailer_env/Reverse-v1"


def test_collect_labels_every_visited_state_with_the_planner() -> None:
    settings = env_settings({"n_trailers": 1})
    envs = ConvoyVectorEnv(ReverseV1Core, 3, autoreset_mode="same_step", n_trailers=1)
    config = PlannerConfig(samples=4, elites=1, iterations=1, tail=10)
    planner = SamplingPlanner(ReverseV1Core, settings, 3, config)
    obs, labels = collect(envs, planner, None, seed=5)
    assert obs.shape == (400 * 3, envs.single_observation_space.shape[0])
    assert labels.shape == (400 * 3, 1)
    assert np.all(np.abs(labels) <= 1.0)
    # The first labels are the planner's decisions at the seeded starts.
    fresh = ConvoyVectorEnv(ReverseV1Core, 3, autoreset_mode="same_step", n_trailers=1)
    first_obs, _ = fresh.reset(seed=5)
    np.testing.assert_array_equal(obs[:3], first_obs)
    again = SamplingPlanner(ReverseV1Core, settings, 3, config)
    np.testing.assert_array_equal(labels[:3, 0], again.plan(fresh.core.z, fresh.core.act)[:, 0])


def test_imitation_run_writes_a_loadable_ppo_model(tmp_path: Path) -> None:
    config = ImitationConfig(
        V1, 1, iterations=2, episodes=4, epochs=2, validation_episodes=4, net_arch=(16,)
    )
    record = imitate(config, tmp_path / "run", verbose=0)
    assert record["recipe"] == "dagger" and record["algo"] == "ppo"
    assert record["timesteps"] == 2 * 4 * 400
    curve = read_curve(tmp_path / "run" / "evaluations.csv")
    assert [row["iteration"] for row in curve] == [0.0, 1.0]
    assert [row["timesteps"] for row in curve] == [1600.0, 3200.0]
    card = json.loads((tmp_path / "run" / "best_model.json").read_text())
    assert card["env_id"] == V1 and card["env_kwargs"] == {"n_trailers": 1}
    assert 0.0 <= card["validation"]["safe_rate"] <= 1.0
    assert card["host"]["ppo_update_s"] > 0 and card["host"]["cpus"] >= 1
    policy = load_policy(str(tmp_path / "run" / "best_model.zip"), V1, {"n_trailers": 1})
    actions = policy(np.zeros((5, 6), dtype=np.float32))
    assert actions.shape == (5, 1) and np.all(np.isfinite(actions))


def test_bad_configurations_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(ValueError, match="no planner"):
        ImitationConfig("trailer_env/Heading-v0", 1)
    with pytest.raises(ValueError, match="iterations"):
        ImitationConfig(V1, 1, iterations=0)
    with pytest.raises(ValueError, match="n_trailers"):
        ImitationConfig(V1, -1)
    with pytest.raises(TypeError, match="episodes"):
        ImitationConfig(V1, 1, episodes=2.5)  # type: ignore[arg-type]
    run = tmp_path / "run"
    run.mkdir()
    (run / "config.json").write_text("{}")
    with pytest.raises(SystemExit) as error:
        main(["--n-trailers", "1", "--run-dir", str(run)])
    assert error.value.code == 2
    assert "--overwrite" in capsys.readouterr().err


def test_the_validation_that_picks_the_kept_iteration_is_sized_by_the_user(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    tiny = ["--n-trailers", "1", "--iterations", "1", "--episodes", "2", "--epochs", "1"]
    main([*tiny, "--net-arch", "8", "--validation-episodes", "3", "--run-dir", str(run)])
    card = json.loads((run / "best_model.json").read_text())
    assert card["imitation"]["validation_episodes"] == 3
    assert card["validation"]["episodes"] == 3
    # The validation seeds (from 50,000) must not reach the selection seeds (60,000).
    assert MAX_VALIDATION_EPISODES == 10_000
    with pytest.raises(ValueError, match="validation_episodes must be <= 10000"):
        ImitationConfig(V1, 1, validation_episodes=10_001)
    refused = tmp_path / "refused"
    with pytest.raises(SystemExit) as error:
        main([*tiny, "--validation-episodes", "10001", "--run-dir", str(refused)])
    assert error.value.code == 2
    assert "--validation-episodes: must be <= 10,000" in capsys.readouterr().err
    assert not refused.exists()


@pytest.mark.slow
def test_imitation_on_the_trailer_sequence_acts_on_unseen_n(tmp_path: Path) -> None:
    from agents.evaluation.metrics import rollout
    from agents.policies.sb3 import TrailersPolicy

    planner = PlannerConfig(samples=4, elites=1, iterations=1, tail=10)
    config = ImitationConfig(
        V1,
        (1, 3),
        iterations=2,
        episodes=4,
        epochs=2,
        validation_episodes=4,
        net_arch=(16,),
        planner=planner,
        observation="trailers",
        max_trailers=6,
    )
    record = imitate(config, tmp_path / "run", verbose=0)
    assert record["policy"] == "MultiInputPolicy" and record["normalize"] is None
    assert record["timesteps"] == 2 * 4 * 400
    card = json.loads((tmp_path / "run" / "best_model.json").read_text())
    assert card["env_kwargs"] == {
        "n_trailers": [1, 3],
        "observation": "trailers",
        "max_trailers": 6,
    }
    assert not (tmp_path / "run" / "best_model_vecnormalize.json").exists()
    model = str(tmp_path / "run" / "best_model.zip")
    for n in (1, 4, 6):  # trained on 1..3: n = 4 and 6 zero-shot
        policy = load_policy(model, V1, {"n_trailers": n})
        assert isinstance(policy, TrailersPolicy) and policy.n == n
        actions = policy(np.zeros((5, 2 * n + 4), dtype=np.float32))
        assert actions.shape == (5, 1) and np.all(np.isfinite(actions))
    results = rollout(load_policy(model, V1, {"n_trailers": 4}), V1, 4, 1000, {"n_trailers": 4})
    assert results.returns.shape == (4,) and np.all(np.isfinite(results.returns))
    with pytest.raises(ValueError, match="reads at most 6 trailers"):
        load_policy(model, V1, {"n_trailers": 7})


def test_the_observation_options_are_checked(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(ValueError, match="max_trailers = 2 holds fewer trailers"):
        ImitationConfig(V1, (1, 3), observation="trailers", max_trailers=2)
    with pytest.raises(ValueError, match="observation must be one of"):
        ImitationConfig(V1, 1, observation="grid")
    with pytest.raises(SystemExit) as error:
        main(["--n-trailers", "1", "--observation", "grid"])
    assert error.value.code == 2
    assert "argument --observation: invalid choice: 'grid'" in capsys.readouterr().err


def _curve_without_time(run: Path) -> list[dict[str, float]]:
    rows = read_curve(run / "evaluations.csv")
    return [{key: value for key, value in row.items() if key != "wall_s"} for row in rows]


def test_a_resumed_run_ends_as_an_uninterrupted_one(tmp_path: Path) -> None:
    settings = {"episodes": 3, "epochs": 2, "validation_episodes": 3, "net_arch": (8,)}
    straight = imitate(ImitationConfig(V1, 1, iterations=2, **settings), tmp_path / "a", verbose=0)
    cut = tmp_path / "b"
    imitate(ImitationConfig(V1, 1, iterations=1, **settings), cut, verbose=0)
    checkpoint = json.loads((cut / "checkpoint.json").read_text())
    assert checkpoint["iterations"] == 1 and checkpoint["rows"] == 3 * 400
    resumed = imitate(ImitationConfig(V1, 1, iterations=2, **settings), cut, 0, resume=True)
    assert resumed["timesteps"] == straight["timesteps"] == 2 * 3 * 400
    assert resumed["simulated_steps"] == straight["simulated_steps"]
    assert resumed["resumed_at"] == [1]
    assert _curve_without_time(cut) == _curve_without_time(tmp_path / "a")
    with np.load(cut / "dataset.npz") as mine, np.load(tmp_path / "a" / "dataset.npz") as theirs:
        np.testing.assert_array_equal(mine["labels"], theirs["labels"])
        np.testing.assert_array_equal(mine["observations"], theirs["observations"])
    policies = [
        load_policy(str(run / "final_model.zip"), V1, {"n_trailers": 1})
        for run in (cut, tmp_path / "a")
    ]
    obs = np.random.default_rng(0).normal(size=(7, 6)).astype(np.float32)
    np.testing.assert_array_equal(policies[0](obs), policies[1](obs))


def test_resume_refuses_what_it_cannot_continue(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from agents.training.imitation_checkpoint import CheckpointError

    settings = {"episodes": 2, "epochs": 1, "validation_episodes": 2, "net_arch": (8,)}
    run = tmp_path / "run"
    imitate(ImitationConfig(V1, 1, iterations=1, **settings), run, verbose=0)
    before = {path.name: path.read_bytes() for path in run.iterdir() if path.is_file()}
    with pytest.raises(CheckpointError, match="has done 1 iterations"):
        imitate(ImitationConfig(V1, 1, iterations=1, **settings), run, 0, resume=True)
    other = ImitationConfig(V1, 1, iterations=3, **{**settings, "epochs": 2})
    with pytest.raises(CheckpointError, match=r"configured differently \(.*imitation.epochs"):
        imitate(other, run, 0, resume=True)
    after = {path.name: path.read_bytes() for path in run.iterdir() if path.is_file()}
    assert after == before  # a refusal changes nothing
    with pytest.raises(SystemExit):
        main(["--n-trailers", "1", "--run-dir", str(tmp_path / "none"), "--resume"])
    assert "no checkpoint" in capsys.readouterr().err


def test_a_mirrored_run_learns_from_mirrored_labels_and_acts_odd(tmp_path: Path) -> None:
    from agents.policies.mirror import MirroredPolicy

    config = ImitationConfig(
        V1, 1, iterations=1, episodes=2, epochs=1, validation_episodes=2, net_arch=(8,), mirror=True
    )
    record = imitate(config, tmp_path / "run", verbose=0)
    assert record["timesteps"] == 2 * 400  # labelled states; the mirrored copies are not
    assert record["imitation"]["mirror"] is True
    signs = np.array([1.0, -1.0, -1.0, 1.0, -1.0, -1.0], dtype=np.float32)
    with np.load(tmp_path / "run" / "dataset.npz") as data:
        labels, obs = data["labels"], data["observations"]
    assert len(labels) == 2 * 2 * 400
    np.testing.assert_array_equal(labels[800:], -labels[:800])
    assert not np.array_equal(obs[800:], obs[:800])  # normalised: mean-shifted, not negated
    policy = load_policy(str(tmp_path / "run" / "best_model.zip"), V1, {"n_trailers": 1})
    assert isinstance(policy, MirroredPolicy)
    straight = np.array([[-1.0, 0.0, 0.0, 1.0, 0.0, 0.0]], dtype=np.float32)
    assert policy(straight)[0, 0] == 0.0
    some = np.random.default_rng(1).normal(size=(5, 6)).astype(np.float32)
    np.testing.assert_allclose(policy(some * signs), -policy(some), atol=1e-6)


def test_a_mirrored_run_over_a_range_of_counts_mirrors_the_padded_layout(tmp_path: Path) -> None:
    config = ImitationConfig(
        V1,
        (1, 2),
        iterations=1,
        episodes=2,
        epochs=1,
        validation_episodes=2,
        net_arch=(8,),
        mirror=True,
    )
    record = imitate(config, tmp_path / "run", verbose=0)
    assert record["imitation"]["mirror"] is True
    with np.load(tmp_path / "run" / "dataset.npz") as data:
        labels = data["labels"]
    half = len(labels) // 2
    np.testing.assert_array_equal(labels[half:], -labels[:half])
    policy = load_policy(str(tmp_path / "run" / "best_model.zip"), V1, {"n_trailers": [1, 2]})
    straight = np.array([[-1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]], dtype=np.float32)
    assert policy(straight)[0, 0] == 0.0  # n = 1 in the layout padded to 2, mask (1, 0)
