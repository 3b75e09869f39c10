"""The generalist: imitate's range of trailer counts and randomised physics, refused on bad
values; the shipped generalist loads and drives mixed and single-n episodes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from agents.commands.imitate import main
from agents.envs import make_vector_env
from agents.oracles.planner import PlannerConfig
from agents.policies.registry import PaddedPolicy, load_policy
from agents.training.imitate import imitate
from agents.training.imitation_config import ImitationConfig
from trailer_env.benchmark import rollout

V1 = "trailer_env/Reverse-v1"
GENERALIST = (
    Path(__file__).resolve().parents[3] / "agents" / "models" / "dagger_reverse_v1_general.zip"
)


def test_the_generalists_configuration() -> None:
    config = ImitationConfig(V1, [1, 3], randomize="mismatch20")  # type: ignore[arg-type]
    assert config.n_trailers == (1, 3)
    assert config.env_kwargs == {"n_trailers": (1, 3), "randomize": "mismatch20"}
    assert config.run_label == "1-3"
    assert sorted(config.settings_by_count()) == [1, 2, 3]
    # Without the new options the keywords are the specialists' (their files unchanged).
    assert ImitationConfig(V1, 2).env_kwargs == {"n_trailers": 2}


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"n_trailers": (3, 1)}, ValueError, "needs low < high"),
        ({"n_trailers": (1, 2, 3)}, TypeError, "pair"),
        ({"n_trailers": (0, 9)}, ValueError, "more than 8"),
        ({"n_trailers": (1, 3), "randomize": "mismatch50"}, ValueError, "unknown preset"),
        ({"n_trailers": 2, "randomize": {"M": (1.2, 0.8)}}, ValueError, "low > high"),
        ({"n_trailers": 2, "randomize": {"b": (0.9, 1.1)}}, ValueError, "unknown name"),
        ({"n_trailers": 2, "randomize": 0.2}, TypeError, "randomize must be"),
    ],
)
def test_bad_generalist_configurations_are_refused(
    kwargs: dict, error: type[Exception], match: str
) -> None:
    with pytest.raises(error, match=match):
        ImitationConfig(V1, **kwargs)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--n-trailers", "3-1"], "needs 0 <= LOW < HIGH"),
        (["--n-trailers", "1-"], "a range LOW-HIGH such as 1-3"),
        (["--n-trailers", "a-b"], "a range LOW-HIGH such as 1-3"),
        (["--n-trailers", "0-9"], "more than 8"),
        (["--n-trailers", "1-3", "--randomize", "mismatch50"], "invalid choice"),
    ],
)
def test_bad_options_exit_before_any_file_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    run = tmp_path / "run"
    export = tmp_path / "export" / "model.zip"
    with pytest.raises(SystemExit) as error:
        main([*argv, "--run-dir", str(run), "--export", str(export)])
    assert error.value.code == 2
    assert message in capsys.readouterr().err
    assert not run.exists() and not export.parent.exists()


def test_a_small_generalist_run(tmp_path: Path) -> None:
    config = ImitationConfig(
        V1,
        (1, 2),
        randomize="mismatch20",
        iterations=2,
        episodes=4,
        epochs=1,
        validation_episodes=4,
        net_arch=(16,),
        planner=PlannerConfig(samples=4, elites=1, iterations=1, horizon=5, tail=10),
    )
    record = imitate(config, tmp_path / "run", verbose=0)
    assert record["timesteps"] == 2 * 4 * 400
    card = json.loads((tmp_path / "run" / "best_model.json").read_text())
    assert card["env_kwargs"] == {"n_trailers": [1, 2], "randomize": "mismatch20"}
    policy = load_policy(str(tmp_path / "run" / "best_model.zip"), V1, {"n_trailers": 1})
    assert isinstance(policy, PaddedPolicy)


def test_the_shipped_generalist_drives_a_mixed_episode() -> None:
    card = json.loads(GENERALIST.with_suffix(".json").read_text())
    assert card["env_kwargs"] == {"n_trailers": [1, 3], "randomize": "mismatch20"}
    kwargs = {"n_trailers": (1, 3), "randomize": "mismatch20"}
    policy = load_policy(str(GENERALIST), V1, kwargs)
    envs = make_vector_env(V1, 12, kwargs)
    obs, infos = envs.reset(seed=1000)
    counts = infos["n_trailers"]
    assert obs.shape == (12, 13) and set(counts.tolist()) <= {1, 2, 3} and len(set(counts)) > 1
    np.testing.assert_array_equal(obs[:, -3:].sum(axis=1), counts)  # the trailer mask
    for _ in range(20):
        actions = policy(obs)
        assert actions.shape == (12, 1) and np.all(np.abs(actions) <= 1.0)
        obs, *_ = envs.step(actions)
    results = rollout(policy, V1, 6, seed=1000, env_kwargs=kwargs)
    assert results.seeds.tolist() == list(range(1000, 1006))
    assert np.all(results.lengths >= 1)


def test_the_shipped_generalist_on_one_n_and_beyond_its_layout() -> None:
    single = load_policy(str(GENERALIST), V1, {"n_trailers": 2})
    assert isinstance(single, PaddedPolicy) and (single.n, single.top) == (2, 3)
    width = make_vector_env(V1, 1, {"n_trailers": 2}).single_observation_space.shape[0]
    assert single(np.zeros((4, width), dtype=np.float32)).shape == (4, 1)
    with pytest.raises(ValueError, match="holds at most 3 trailers"):
        load_policy(str(GENERALIST), V1, {"n_trailers": 4})
    with pytest.raises(ValueError, match="holds at most 3 trailers"):
        load_policy(str(GENERALIST), V1, {"n_trailers": 4}, force=True)
