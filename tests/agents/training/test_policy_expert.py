"""``--expert specialists``: trained policies as DAgger's expert (policy distillation).

Each row of a mixed-n batch is labelled by the specialist of its own n, from the
observation that count's env shows; the label is a function of that observation; the
options refused are refused before anything is written (with the other experts' in
test_imitate_experts.py)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from agents.commands import imitate as imitate_command
from agents.envs import env_settings
from agents.policies.experts import EXPERTS, PolicyExpert, PolicyExpertConfig
from agents.policies.registry import load_policy
from agents.training.imitation_checkpoint import DATASET_FILE
from agents.training.imitation_config import ImitationConfig
from trailer_env.mixed import MixedCore
from trailer_env.registry import core_class_of
from trailer_env.scenes.reverse_v1 import ReverseV1Core
from trailer_env.vector import ConvoyVectorEnv

V1 = "trailer_env/Reverse-v1"
DOCK = "trailer_env/Dock-v0"


def test_the_table_holds_the_planners_then_the_specialists() -> None:
    assert list(EXPERTS) == ["mpc", "ilqr", "specialists"]
    specialists = EXPERTS["specialists"]
    assert specialists.fits(V1) and specialists.fits("trailer_env/Heading-v0")
    assert specialists.problem(V1, (1, 6), None) is None
    assert specialists.problem(V1, (1, 3), "mismatch20") is None  # a policy acts on what it reads
    assert specialists.configure(policy="ppo_dock_n{n}") == PolicyExpertConfig("ppo_dock_n{n}")
    assert specialists.configure(policy=None) == PolicyExpertConfig("dagger_reverse_v1_n{n}")
    with pytest.raises(TypeError, match="takes no planner option 'samples'"):
        specialists.configure(samples=4)
    with pytest.raises(TypeError, match="takes no planner option 'policy'"):
        EXPERTS["mpc"].configure(policy="dagger_reverse_v1_n{n}")
    config = ImitationConfig(V1, (1, 2), expert="specialists")
    assert config.expert_config == PolicyExpertConfig()


@pytest.mark.parametrize(
    ("policy", "error", "match"),
    [
        (3, TypeError, "policy must be a str, got int"),
        ("dagger_reverse_v1_n{m}", ValueError, r"the only field a policy spec may hold is \{n\}"),
        ("dagger_{}", ValueError, r"the only field a policy spec may hold is \{n\}"),
    ],
)
def test_a_bad_policy_spec_is_refused(policy: object, error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        PolicyExpertConfig(policy)  # type: ignore[arg-type]


def test_a_range_needs_the_count_in_the_spec() -> None:
    settings = {n: env_settings({"n_trailers": n}) for n in (1, 2)}
    with pytest.raises(ValueError, match=r"name one policy for counts \[1, 2\]"):
        PolicyExpert(ReverseV1Core, settings, 4, PolicyExpertConfig("dagger_reverse_v1_n1"))


def test_each_row_is_labelled_by_its_own_counts_policy() -> None:
    envs = ConvoyVectorEnv(ReverseV1Core, 8, autoreset_mode="same_step", n_trailers=(1, 2))
    envs.reset(seed=5)
    settings = {n: env_settings({"n_trailers": n}) for n in (1, 2)}
    expert = PolicyExpert(ReverseV1Core, settings, 8)
    core = envs.core
    assert isinstance(core, MixedCore)  # a range of counts
    for _ in range(3):  # a few steps, so the labels are not only the starts'
        labels = expert.label(core)
        assert labels.shape == (8, 1) and np.all(np.abs(labels) <= 1.0)
        counts = core.trailers
        assert set(counts.tolist()) == {1, 2}
        for n in (1, 2):
            rows = np.flatnonzero(counts == n)
            own = load_policy(f"dagger_reverse_v1_n{n}", V1, {"n_trailers": n})
            np.testing.assert_array_equal(labels[rows], own(core.cores[n].obs[rows]))
        np.testing.assert_array_equal(expert.label(core), labels)  # no state kept
        envs.step(labels.astype(np.float32))
    assert expert.simulated_steps == 0 and expert.random_streams() == []


def test_one_count_reads_the_scene_core() -> None:
    envs = ConvoyVectorEnv(core_class_of(DOCK), 4, autoreset_mode="same_step", n_trailers=2)
    envs.reset(seed=9)
    expert = PolicyExpert(
        core_class_of(DOCK),
        {2: env_settings({"n_trailers": 2})},
        4,
        PolicyExpertConfig("ppo_dock_n2"),
    )
    own = load_policy("ppo_dock_n2", DOCK, {"n_trailers": 2})
    np.testing.assert_array_equal(expert.label(envs.core)[:, 0], own(envs.core.obs)[:, 0])


def test_a_policy_of_another_n_is_refused() -> None:
    settings = {3: env_settings({"n_trailers": 3})}
    with pytest.raises(ValueError, match="n_trailers"):
        PolicyExpert(ReverseV1Core, settings, 2, PolicyExpertConfig("dagger_reverse_v1_n2"))


def test_a_tiny_distillation_labels_the_same_states_the_same_twice(tmp_path: Path) -> None:
    tiny = [
        "--n-trailers", "1-2", "--expert", "specialists", "--observation", "trailers",
        "--iterations", "2", "--episodes", "2", "--epochs", "1", "--seed", "4",
    ]  # fmt: skip
    datasets = []
    for run in ("a", "b"):
        run_dir = tmp_path / run
        assert imitate_command.main([*tiny, "--run-dir", str(run_dir)]) == 0
        with np.load(run_dir / DATASET_FILE) as data:
            datasets.append((data["observations"], data["labels"]))
        card = json.loads((run_dir / "best_model.json").read_text())
        assert card["expert"] == "specialists"
        assert card["planner"] == {"policy": "dagger_reverse_v1_n{n}"}
        assert card["simulated_steps"] == 0 and card["timesteps"] == 2 * 2 * 400
    (obs_a, labels_a), (obs_b, labels_b) = datasets
    assert labels_a.shape == (1600, 1)
    np.testing.assert_array_equal(obs_a, obs_b)
    np.testing.assert_array_equal(labels_a, labels_b)
    assert np.unique(labels_a).size > 100


def test_counts_pick_their_policies() -> None:
    config = PolicyExpertConfig("1-3=ppo_reverse_v1_n{n}, 5=my_n5.zip ,dagger_reverse_v1_n{n}")
    assert [config.spec(n) for n in (1, 3, 4, 5, 6)] == [
        "ppo_reverse_v1_n1",
        "ppo_reverse_v1_n3",
        "dagger_reverse_v1_n4",
        "my_n5.zip",
        "dagger_reverse_v1_n6",
    ]
    assert not config.is_one_policy() and PolicyExpertConfig("ppo_dock_n2").is_one_policy()
    with pytest.raises(ValueError, match="name no policy for n = 4"):
        PolicyExpertConfig("1-3=ppo_reverse_v1_n{n}").spec(4)


@pytest.mark.parametrize(
    ("policy", "match"),
    [
        ("a{n},b{n}", "more than one item without counts"),
        ("0-2=a{n},b{n}", r"counts '0-2' are not N or LOW-HIGH in 1\.\.256"),
        ("3-2=a{n}", r"counts '3-2' are not N or LOW-HIGH"),
        ("x=a{n}", r"counts 'x' are not N or LOW-HIGH"),
        ("1-2=,b{n}", "an item names no policy"),
    ],
)
def test_a_bad_list_of_policies_is_refused(policy: str, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        PolicyExpertConfig(policy)


def test_the_parameter_features_are_what_an_observing_env_shows() -> None:
    plain = ConvoyVectorEnv(ReverseV1Core, 6, n_trailers=2, randomize="mismatch20")
    observing = ConvoyVectorEnv(
        ReverseV1Core, 6, n_trailers=2, randomize="mismatch20", observe_params=True
    )
    obs, _ = plain.reset(seed=3)
    seen, _ = observing.reset(seed=3)
    np.testing.assert_array_equal(seen[:, : obs.shape[1]], obs)
    features = plain.core.parameter_features()
    np.testing.assert_array_equal(seen[:, obs.shape[1] :], features.astype(np.float32))
    assert np.all(np.abs(features[:, [0, 1, 2, 5, 6]]) > 0.0)  # M, J0, a, l, mu drawn
    np.testing.assert_array_equal(features[:, [3, 4]], 0.0)  # m, J: not randomised


def _privileged_policy(folder: Path) -> Path:
    """An untrained PPO of Reverse-v1 n = 2 that reads the parameter features, with a card."""
    from stable_baselines3 import PPO

    from agents.artifacts.cards import ModelCard, write_card
    from agents.artifacts.sb3_zip import save_model
    from trailer_env.sb3 import ConvoySB3VecEnv

    kwargs = {"n_trailers": 2, "randomize": "mismatch20", "observe_params": True}
    venv = ConvoySB3VecEnv(V1, num_envs=2, **kwargs)
    model = PPO("MlpPolicy", venv, n_steps=8, batch_size=16, seed=0, device="cpu")
    path = save_model(model, folder / "privileged_n2.zip")
    card = ModelCard.from_json({"env_id": V1, "algo": "ppo", "env_kwargs": kwargs})
    write_card(path, card)
    return path


def test_a_privileged_policy_reads_each_rows_parameters(tmp_path: Path) -> None:
    path = _privileged_policy(tmp_path)
    envs = ConvoyVectorEnv(ReverseV1Core, 8, autoreset_mode="same_step", n_trailers=(1, 2),
                           randomize="mismatch20")  # fmt: skip
    envs.reset(seed=11)
    settings = {n: env_settings({"n_trailers": n, "randomize": "mismatch20"}) for n in (1, 2)}
    config = PolicyExpertConfig(f"1=dagger_reverse_v1_n1,{path}")
    expert = PolicyExpert(ReverseV1Core, settings, 8, config)
    assert expert.privileged == {2}
    labels = expert.label(envs.core)
    rows = np.flatnonzero(envs.core.trailers == 2)
    core = envs.core.cores[2]
    expert_policy = load_policy(str(path), V1, {"n_trailers": 2, "observe_params": True})
    features = core.parameter_features(rows).astype(np.float32)
    seen = np.hstack([core.obs[rows], features])
    np.testing.assert_array_equal(labels[rows], expert_policy(seen))
    nominal = np.hstack([core.obs[rows], np.zeros_like(features)])
    assert np.all(labels[rows] != expert_policy(nominal))  # the parameters change its action
    one = envs.core.cores[1]
    ones = np.flatnonzero(envs.core.trailers == 1)
    own = load_policy("dagger_reverse_v1_n1", V1, {"n_trailers": 1})
    np.testing.assert_array_equal(labels[ones], own(one.obs[ones]))  # not privileged: as before
    with pytest.raises(ValueError, match="observation"):
        load_policy(str(path), V1, {"n_trailers": 2})  # only with its parameters
