"""The experts of DAgger: the table, the deterministic ``ilqr`` expert's labels (the same
states get the same actions in two runs), the scene defaults and refused combinations."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest

from agents.artifacts.curves import read_curve
from agents.commands import imitate as imitate_command
from agents.envs import env_settings
from agents.oracles.ilqr import ILQRConfig
from agents.oracles.labellers import ILQRExpert
from agents.oracles.planner import PlannerConfig
from agents.policies.experts import EXPERTS, default_expert
from agents.training.imitation_checkpoint import DATASET_FILE
from agents.training.imitation_config import ImitationConfig
from trailer_env.scenes.dock import DockCore
from trailer_env.vector import ConvoyVectorEnv

V1 = "trailer_env/Reverse-v1"
DOCK = "trailer_env/Dock-v0"
COMMITTED_N3 = (
    Path(__file__).resolve().parents[3] / "agents" / "models" / "dagger_reverse_v1_n3.json"
)
#: A tiny budget: 2 iterations of 2 convoys, a 5-step plan with one iLQR iteration.
TINY = [
    "--n-trailers",
    "1",
    "--seed",
    "3",
    "--expert",
    "ilqr",
    "--iterations",
    "2",
    "--episodes",
    "2",
    "--epochs",
    "1",
    "--net-arch",
    "8",
    "--planner-horizon",
    "5",
    "--planner-iterations",
    "1",
]


def test_the_table_and_the_scene_defaults() -> None:
    assert list(EXPERTS) == ["mpc", "ilqr", "specialists"]
    scenes = ("Reverse-v0", "Reverse-v1", "Dock-v0", "Coast-v0")
    defaults = [default_expert(f"trailer_env/{scene}") for scene in scenes]
    assert defaults == ["mpc", "mpc", "ilqr", "ilqr"]
    assert [name for name, expert in EXPERTS.items() if expert.fits(DOCK)] == [
        "ilqr",
        "specialists",
    ]
    assert [name for name, expert in EXPERTS.items() if expert.fits(V1)] == [
        "mpc",
        "ilqr",
        "specialists",
    ]
    with pytest.raises(ValueError, match="Heading-v0 has no planner to imitate"):
        default_expert("trailer_env/Heading-v0")
    # The default on Reverse is the committed runs' expert with their settings.
    config = ImitationConfig(V1, 3)
    committed = json.loads(COMMITTED_N3.read_text())
    assert config.expert == committed["expert"] == "mpc"
    assert asdict(config.expert_config) == committed["planner"]
    dock = ImitationConfig(DOCK, 1)
    assert dock.expert == "ilqr" and dock.expert_config == ILQRConfig(reuse=False)
    assert EXPERTS["mpc"].configure(samples=32) == PlannerConfig(samples=32, elites=8)
    assert EXPERTS["ilqr"].configure(horizon=7, iterations=None) == ILQRConfig(
        horizon=7, reuse=False
    )


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        (
            {"env_id": DOCK, "expert": "mpc"},
            ValueError,
            "the mpc expert has no cost for trailer_env/Dock-v0; use ilqr",
        ),
        ({"env_id": "trailer_env/Heading-v0"}, ValueError, "no planner to imitate"),
        (
            {"n_trailers": (1, 3), "expert": "ilqr"},
            ValueError,
            "one count of trailers, not a range \\(1-3\\)",
        ),
        (
            {"randomize": "mismatch20", "expert": "ilqr"},
            ValueError,
            "cannot label randomised physical parameters",
        ),
        ({"expert": "cem"}, ValueError, "unknown 'cem'"),
        ({"expert": 1}, TypeError, "expert must be a str, got int"),
        (
            {"expert": "ilqr", "planner": PlannerConfig()},
            TypeError,
            "the ilqr expert takes ILQRConfig, got PlannerConfig",
        ),
        (
            {"convoy_direction": "tail_first"},
            ValueError,
            "convoy_direction='tail_first' needs observation='trailers'",
        ),
        (
            {"convoy_direction": "up", "observation": "trailers"},
            ValueError,
            "convoy_direction must be one of \\('cart_first', 'tail_first', 'both'\\), got 'up'",
        ),
        ({"convoy_direction": None}, TypeError, "convoy_direction must be a str, got NoneType"),
    ],
)
def test_refused_combinations(kwargs: dict, error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        ImitationConfig(**{"env_id": V1, "n_trailers": 1, **kwargs})


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["--env", DOCK, "--expert", "mpc"],
            "argument --expert: the mpc expert has no cost for trailer_env/Dock-v0; use ilqr",
        ),
        (
            ["--env", DOCK, "--planner-samples", "8"],
            "argument --expert: the ilqr expert takes "
            "no planner option 'samples' (it takes iterations, horizon)",
        ),
        (
            ["--planner-horizon", "8"],
            "argument --expert: the mpc expert takes no planner "
            "option 'horizon' (it takes samples, iterations)",
        ),
        (["--expert", "ilqr", "--n-trailers", "1-3"], "one count of trailers, not a range"),
        (["--expert", "ilqr", "--randomize", "mismatch10"], "cannot label randomised"),
        (
            ["--expert", "ilqr", "--planner-horizon", "201"],
            "argument --planner-horizon: must be <= 200",
        ),
        (
            ["--env", "trailer_env/Heading-v0"],
            "argument --expert: trailer_env/Heading-v0 has no planner to imitate",
        ),
        (
            ["--expert", "mpc", "--expert-policy", "ppo_dock_n{n}"],
            "argument --expert: the mpc expert takes no planner option 'policy'",
        ),
        (
            ["--expert", "specialists", "--n-trailers", "1-2", "--planner-samples", "4"],
            "argument --expert: the specialists expert takes no planner option 'samples'",
        ),
        (
            ["--expert", "specialists", "--expert-policy", "x{m}"],
            "the only field a policy spec may hold is {n}",
        ),
        (
            ["--expert", "specialists", "--n-trailers", "1-2", "--expert-policy", "ppo_dock_n2"],
            "name one policy for counts [1, 2]",
        ),
        (
            [
                "--expert",
                "specialists",
                "--n-trailers",
                "1-3",
                "--expert-policy",
                "1-2=dagger_reverse_v1_n{n}",
            ],
            "expert policy of n = 3: expert policies '1-2=dagger_reverse_v1_n{n}' name no policy "
            "for n = 3",
        ),
        (
            [
                "--expert",
                "specialists",
                "--n-trailers",
                "1-2",
                "--teacher",
                "dagger_reverse_v1_n2,1=dagger_reverse_v1_n2",
            ],
            "with n_trailers = 2, not trailer_env/Reverse-v1 with n_trailers = 1",
        ),
        (["--history", "65"], "history must be an integer in [0, 64], got 65"),
        (
            ["--history", "4", "--observation", "trailers"],
            "history = 4 needs observation='flat' (the flat student)",
        ),
    ],
)
def test_refused_options_exit_before_anything_is_written(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    argv: list[str],
    message: str,
) -> None:
    monkeypatch.chdir(tmp_path)
    export = tmp_path / "export" / "model.zip"
    with pytest.raises(SystemExit) as error:
        imitate_command.main([*argv, "--export", str(export)])
    assert error.value.code == 2
    assert message in capsys.readouterr().err.strip().splitlines()[-1]
    assert list(tmp_path.iterdir()) == []


def test_teacher_is_the_expert_policy_option_the_recorded_commands_use() -> None:
    parser = imitate_command.build_parser()
    for flag in ("--expert-policy", "--teacher"):
        args = parser.parse_args([flag, "1-2=ppo_reverse_v1_n{n},dagger_reverse_v1_n{n}"])
        assert args.expert_policy == "1-2=ppo_reverse_v1_n{n},dagger_reverse_v1_n{n}"
    assert parser.parse_args([]).expert_policy is None


def test_the_default_run_folder_names_a_non_default_expert(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    folders: list[tuple[str, str]] = []
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(imitate_command, "limit_torch_threads", lambda: None)
    monkeypatch.setattr(
        imitate_command,
        "imitate",
        lambda config, run_dir, resume=False, command=None: folders.append(
            (str(config.expert), run_dir.name)
        ),
    )
    for argv in (["--expert", "ilqr"], ["--expert", "mpc"], ["--env", DOCK]):
        assert imitate_command.main(["--n-trailers", "1", *argv]) == 0
    assert folders == [
        ("ilqr", "reverse_v1_n1_dagger_s0_ilqr"),
        ("mpc", "reverse_v1_n1_dagger_s0"),
        ("ilqr", "dock_n1_dagger_s0"),
    ]


def test_the_ilqr_expert_labels_a_state_whatever_it_labelled_before() -> None:
    settings = env_settings({"n_trailers": 1})
    config = ILQRConfig(reuse=False, horizon=5, iterations=1)
    envs = ConvoyVectorEnv(DockCore, 3, autoreset_mode="same_step", n_trailers=1)
    envs.reset(seed=40)
    start_z, start_act = envs.core.z.copy(), envs.core.act.copy()
    first = ILQRExpert(DockCore, {1: settings}, 3, config).label(envs.core)
    expert = ILQRExpert(DockCore, {1: settings}, 3, config)
    for _ in range(4):  # label other states first: with reuse off they leave no trace
        envs.step(expert.label(envs.core).astype(np.float32))
    moved = envs.core.z.copy()
    envs.core.z[:], envs.core.act[:] = start_z, start_act
    envs.core.refresh()
    np.testing.assert_array_equal(expert.label(envs.core), first)
    assert not np.array_equal(moved, start_z)
    # (1 + 1) iterations x 4 candidates x 5 steps of rollouts, and 1 iteration x 6 steps
    # x 10 perturbed copies (d = 8: Dock's z with its pose, plus s and s_dot).
    assert expert.steps_per_label == expert.planner.steps_per_decision == 40 + 60
    assert np.all(np.abs(first) <= 1.0)


@pytest.mark.slow
@pytest.mark.parametrize("env_id", [V1, DOCK])
def test_a_tiny_ilqr_run_labels_the_same_states_the_same_twice(tmp_path: Path, env_id: str) -> None:
    datasets = []
    for run in ("a", "b"):
        run_dir = tmp_path / run
        assert imitate_command.main([*TINY, "--env", env_id, "--run-dir", str(run_dir)]) == 0
        with np.load(run_dir / DATASET_FILE) as data:
            datasets.append((data["observations"], data["labels"]))
        card = json.loads((run_dir / "best_model.json").read_text())
        assert card["expert"] == "ilqr" and card["env_id"] == env_id
        assert card["planner"]["horizon"] == 5 and card["planner"]["reuse"] is False
        assert card["planner"]["iterations"] == 1
        assert card["timesteps"] == 2 * 2 * 400
        curve = read_curve(run_dir / "evaluations.csv")
        assert [row["timesteps"] for row in curve] == [800.0, 1600.0]
        assert {path.name for path in run_dir.iterdir()} >= {
            "best_model.zip",
            "final_model.zip",
            "best_model.json",
            "evaluations.csv",
            "best_model_vecnormalize.json",
            "config.json",
            DATASET_FILE,
        }
    (obs_a, labels_a), (obs_b, labels_b) = datasets
    assert obs_a.shape == (1600, obs_b.shape[1]) and labels_a.shape == (1600, 1)
    np.testing.assert_array_equal(obs_a, obs_b)
    np.testing.assert_array_equal(labels_a, labels_b)
    assert np.all(np.abs(labels_a) <= 1.0) and np.unique(labels_a).size > 100
