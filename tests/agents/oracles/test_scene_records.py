"""The planners' per-scene records: the one place that says what a planner does with a
scene, so that a new scene is one record (and a scene without one has no planner)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from agents.certification.certify import PLANNERS, certified_scenes, certify, planner_problem
from agents.envs import ENV_IDS, env_settings
from agents.oracles.ilqr_costs import CostWeights, SceneCost, scene_horizon, scene_weights
from agents.oracles.ilqr_policy import ILQRPolicy
from agents.oracles.scenes import NO_ORACLE, SCENE_ORACLES, SceneOracle, scene_oracle
from agents.policies.baselines import BASELINES, applicable_baselines, make_baseline
from agents.policies.experts import EXPERTS, default_expert
from trailer_env.objective import Objective
from trailer_env.registry import core_class_of
from trailer_env.scenes import DockCore, HeadingCore, ReverseV1Core

HEADING = "trailer_env/Heading-v0"


def test_every_record_names_a_scene_and_known_planners() -> None:
    scenes = {core_class_of(env_id).scene for env_id in ENV_IDS}
    assert set(SCENE_ORACLES) <= scenes
    for record in SCENE_ORACLES.values():
        assert set(record.planners) <= set(BASELINES)
        assert set(record.weights) <= {field.name for field in dataclasses.fields(CostWeights)}
        assert {name for name, _ in record.task_residuals} <= set(record.weights)
    # The scene says what it asks; the certifying planners follow it and the records.
    objectives = {
        "Reverse-v0": Objective.SURVIVAL,
        "Reverse-v1": Objective.SURVIVAL,
        "Coast-v0": Objective.GOAL,
        "Heading-v0": Objective.GOAL,
        "Dock-v0": Objective.GOAL,
    }
    assert {name: core_class_of(f"trailer_env/{name}").objective for name in objectives} == (
        objectives
    )
    assert (certified_scenes("mpc"), certified_scenes("ilqr")) == (["Reverse"], ["Coast", "Dock"])
    assert scene_oracle(HEADING) is scene_oracle(HeadingCore) is NO_ORACLE
    assert scene_oracle("trailer_env/Reverse-v1") is SCENE_ORACLES["Reverse"]


def test_the_baselines_that_fit_are_the_core_s_then_the_record_s() -> None:
    assert applicable_baselines("trailer_env/Reverse-v1") == (
        "zero",
        "random",
        "lqr",
        "mpc",
        "mpc-replay",
        "ilqr",
    )
    assert applicable_baselines("trailer_env/Dock-v0") == ("zero", "random", "lqr", "ilqr")
    assert applicable_baselines(HEADING) == ("zero", "random", "lqr", "heading-p")
    with pytest.raises(ValueError, match="the ilqr baseline is for trailer_env/Reverse-v0, "):
        make_baseline("ilqr", env_settings(), HEADING)


def test_the_records_hold_the_ilqr_defaults() -> None:
    horizons = {"Reverse-v1": 60, "Coast-v0": 60, "Heading-v0": 60, "Dock-v0": 100}
    assert {name: scene_horizon(core_class_of(f"trailer_env/{name}")) for name in horizons} == (
        horizons
    )
    assert scene_weights(ReverseV1Core) == CostWeights()
    assert scene_weights(DockCore) == dataclasses.replace(
        CostWeights(), angle=0.1, omega=0.05, rail=0.5, lateral=2.0, heading=2.0, terminal=1.0
    )
    # n = 2: 2n + 3 convoy residuals, the band's, Reverse-v1's speed hinge, Dock's two.
    assert SceneCost(ReverseV1Core, env_settings()).size == 9
    assert SceneCost(DockCore, env_settings()).size == 10


def test_a_new_scene_is_one_record(monkeypatch: pytest.MonkeyPatch) -> None:
    """Heading-v0 has no planner; one record makes iLQR plan it, with a task residual of
    its own, and the DAgger expert, the baseline and certification (its objective is a
    goal) follow."""

    def heading_error(core: object) -> np.ndarray:
        return np.asarray(core.heading_error)  # type: ignore[attr-defined]

    record = SceneOracle(
        planners=("ilqr",),
        horizon=7,
        weights={"heading": 4.0},
        task_residuals=(("heading", heading_error),),
    )
    monkeypatch.setitem(SCENE_ORACLES, "Heading", record)
    assert certified_scenes("ilqr") == ["Coast", "Heading", "Dock"]
    assert planner_problem(HEADING, None) is None and default_expert(HEADING) == "ilqr"
    assert EXPERTS["ilqr"].problem(HEADING, 2, None) is None
    assert scene_horizon(HeadingCore) == 7
    assert scene_weights(HeadingCore).heading == 4.0
    settings = env_settings({"n_trailers": 2})
    cost = SceneCost(HeadingCore, settings)
    assert cost.size == 9  # 2n + 3 of the convoy, the band's, and the record's one
    core = HeadingCore(settings, 3)
    core.reset_rows(np.arange(3), [np.random.default_rng(seed) for seed in range(3)])
    residuals = cost.stage_residuals(core)
    np.testing.assert_array_equal(residuals[:, -1], 2.0 * core.heading_error)
    assert isinstance(make_baseline("ilqr", settings, HEADING), ILQRPolicy)


def test_the_certifying_planner_follows_the_scene_s_kind(monkeypatch: pytest.MonkeyPatch) -> None:
    assert {name: certifier.objective for name, certifier in PLANNERS.items()} == {
        "mpc": Objective.SURVIVAL,
        "ilqr": Objective.GOAL,
    }
    assert planner_problem("trailer_env/Reverse-v1", "ilqr") == (
        "trailer_env/Reverse-v1 is certified by surviving the full episode with the sampling "
        "planner; use --planner mpc (ilqr certifies the goal scenes Coast and Dock)"
    )
    assert planner_problem("trailer_env/Coast-v0", "ilqr") is None
    # Heading is a goal scene without a planner: nothing certifies it, before any work.
    refusal = (
        "no planner certifies trailer_env/Heading-v0: its scene's record "
        "(agents.oracles.scenes) does not name ilqr, the planner of its goal objective"
    )
    assert planner_problem(HEADING, None) == planner_problem(HEADING, "ilqr") == refusal
    with pytest.raises(ValueError, match="no planner certifies trailer_env/Heading-v0"):
        certify(HEADING, 1, [1000])
    monkeypatch.setitem(SCENE_ORACLES, "Heading", SceneOracle(planners=("ilqr",)))
    assert planner_problem(HEADING, "ilqr") is None
    assert "does not steer it to trailer_env/Heading-v0's goal" in str(
        planner_problem(HEADING, "mpc")
    )
