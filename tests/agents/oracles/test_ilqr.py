"""The iLQR planner: deterministic to the bit, inside the box, and better than the LQR."""

from __future__ import annotations

from typing import TypeVar

import gymnasium as gym
import numpy as np
import pytest

import trailer_env  # noqa: F401  (registers the ids)
from agents.oracles.ilqr import ILQRConfig, ILQRPlanner
from agents.oracles.ilqr_costs import CostWeights, SceneCost
from agents.oracles.scenes import dock_state_from_observation
from agents.policies.baselines import make_baseline
from trailer_env.controllers import LQRController
from trailer_env.core import ConvoyCore
from trailer_env.scenes.dock import DockCore
from trailer_env.scenes.reverse_v1 import ReverseV1Core
from trailer_env.settings import settings_from_kwargs
from trailer_env.vector import seed_generators

DOCK = "trailer_env/Dock-v0"
#: A Dock-v0 start (n = 1, validation seed) the LQR misses and the planner docks.
DOCKED_SEED = 50003
#: A Reverse-v1 start (n = 2, validation seed) the LQR folds and the planner keeps safe.
RESCUED_SEED = 50012


CoreT = TypeVar("CoreT", bound=ConvoyCore)


def reset_core(core_class: type[CoreT], n: int, seeds: list[int]) -> CoreT:
    core = core_class(settings_from_kwargs(n_trailers=n), len(seeds))
    core.reset_rows(np.arange(len(seeds)), seed_generators(seeds, len(seeds), None))
    return core


def task_of(core: ConvoyCore) -> dict[str, np.ndarray]:
    return {key: getattr(core, key).copy() for key in type(core).task_keys}


def test_same_state_gives_the_same_action_bits() -> None:
    core = reset_core(ReverseV1Core, 2, [50000, 50001, 50002])
    settings = core.settings
    first = ILQRPlanner(ReverseV1Core, settings, 3)
    second = ILQRPlanner(ReverseV1Core, settings, 3)
    alone = ILQRPlanner(ReverseV1Core, settings, 1)  # the same start in another batch
    for _ in range(3):
        a = first.plan(core.z, core.act)
        b = second.plan(core.z, core.act)
        c = alone.plan(core.z[1:2], core.act[1:2])
        assert a.view(np.uint64).tolist() == b.view(np.uint64).tolist()
        assert a[1:2].view(np.uint64).tolist() == c.view(np.uint64).tolist()
        core.step(a)
    # Without reuse the action is a function of the state alone.
    config = ILQRConfig(reuse=False, iterations=2)
    fresh = ILQRPlanner(ReverseV1Core, settings, 3, config).plan(core.z, core.act)
    used = ILQRPlanner(ReverseV1Core, settings, 3, config)
    used.plan(core.z[[2, 0, 1]], core.act[[2, 0, 1]])
    assert fresh.view(np.uint64).tolist() == used.plan(core.z, core.act).view(np.uint64).tolist()


def test_without_iterations_it_plays_the_lqr() -> None:
    core = reset_core(ReverseV1Core, 2, [50003, 50004])
    twin = reset_core(ReverseV1Core, 2, [50003, 50004])
    planner = ILQRPlanner(ReverseV1Core, core.settings, 2, ILQRConfig(iterations=0, reuse=False))
    lqr = LQRController(core.settings)
    for _ in range(10):
        core.step(planner.plan(core.z, core.act))
        # The LQR may ask the servo for more than the bound, which the servo clips; the
        # planner asks for the bound: the same acceleration. (The LQR reads float32.)
        twin.step(lqr(twin.obs).astype(np.float64))
        np.testing.assert_allclose(core.act[:, 5], twin.act[:, 5], atol=1e-4)
        np.testing.assert_allclose(core.z, twin.z, atol=1e-6)


def test_forward_and_central_differences_agree() -> None:
    core = reset_core(ReverseV1Core, 2, [50005, 50006])
    central = ILQRPlanner(ReverseV1Core, core.settings, 2, ILQRConfig(central=True))
    forward = ILQRPlanner(ReverseV1Core, core.settings, 2, ILQRConfig(horizon=central.horizon))
    central.plan(core.z, core.act)
    nominal = central.last
    exact = central._derivatives(nominal)
    approximate = forward._derivatives(nominal)
    for name, one, other in zip(("A", "B", "J", "JT"), exact, approximate, strict=True):
        scale = np.max(np.abs(one))
        assert scale > 0.0, name
        np.testing.assert_allclose(other, one, atol=1e-3 * scale, err_msg=name)
    # A step's Jacobian is near the identity (dt = 0.05 s), B moves the mass's speed.
    np.testing.assert_allclose(np.diagonal(exact[0], axis1=2, axis2=3), 1.0, atol=0.2)
    assert np.all(np.abs(exact[1][:, :, -1]) > 0.0)


def test_actions_stay_in_the_box_near_the_rail_ends() -> None:
    settings = settings_from_kwargs(n_trailers=2)
    s_max = settings.params.s_max
    accel = settings.rail_accel_max
    core = ReverseV1Core(settings, 6)
    ends = [(0.999, 0.0), (-0.999, 0.0), (0.9, 0.9), (-0.9, -0.9), (0.0, 1.0), (0.5, -0.99)]
    for i, (place, speed) in enumerate(ends):
        s = place * s_max
        # The fastest speed towards the nearer end that can still stop before it.
        room = s_max - abs(s)
        s_dot = speed * np.sqrt(2 * accel * room) * 0.999 if speed else 0.0
        core.set_row_state(i, [-1.0, 0.02 * (i - 2), 0.03, -0.02], s=s, s_dot=s_dot)
    planner = ILQRPlanner(ReverseV1Core, settings, 6)
    for _ in range(10):
        actions = planner.plan(core.z, core.act)
        assert actions.dtype == np.float64 and actions.shape == (6, 1)
        assert np.all(np.abs(actions) <= 1.0)
        for trajectory_actions in (planner.last.actions, planner.last.v):
            assert np.all(np.abs(trajectory_actions) <= 1.0)
        core.step(actions)
        assert np.all(np.abs(core.act[:, 1]) <= s_max)


def test_the_planner_docks_a_start_the_lqr_misses() -> None:
    env = gym.make(DOCK, n_trailers=1)
    obs, _ = env.reset(seed=DOCKED_SEED)
    lqr = make_baseline("lqr", settings_from_kwargs(n_trailers=1), DOCK)
    for _ in range(400):
        obs, _, terminated, truncated, info = env.step(lqr(obs[None])[0])
        if terminated or truncated:
            break
    assert not info["is_success"]
    core = reset_core(DockCore, 1, [DOCKED_SEED])
    planner = ILQRPlanner(DockCore, core.settings, 1)
    steps = 0
    while steps < 400 and not core.terminated[0]:
        core.step(planner.plan(core.z, core.act, task_of(core)))
        steps += 1
    assert core.success[0], f"ended after {steps} steps at {core.dock_xy[0]}"
    assert core.dock_distance()[0] < 0.3


def test_the_planner_keeps_a_reverse_start_safe() -> None:
    core = reset_core(ReverseV1Core, 2, [RESCUED_SEED])
    lqr = LQRController(core.settings)
    folded = False
    for _ in range(400):
        core.step(lqr(core.obs).astype(np.float64))
        if core.terminated[0]:
            folded = True
            break
    assert folded
    core = reset_core(ReverseV1Core, 2, [RESCUED_SEED])
    planner = ILQRPlanner(ReverseV1Core, core.settings, 1)
    band = 0
    for _ in range(400):
        core.step(planner.plan(core.z, core.act))
        band += int(core.cost[0] > 0.0)
        assert not core.terminated[0]
    assert band == 0
    assert np.max(np.abs(core.z[0, 2:4])) < 0.3


def test_dock_observation_gives_back_the_state() -> None:
    core = reset_core(DockCore, 2, [50000, 50001, 50002])
    for _ in range(20):
        core.step(np.full((3, 1), 0.4))
    z, act, target = dock_state_from_observation(core.obs, core.settings)
    copy = DockCore(core.settings, 3)
    copy.z[:], copy.act[:], copy.target[:] = z, act, target
    copy.refresh()
    np.testing.assert_allclose(copy.dock_xy, core.dock_xy, atol=1e-5)
    np.testing.assert_allclose(copy.dock_heading_error, core.dock_heading_error, atol=1e-6)
    np.testing.assert_array_equal(copy.obs, core.obs)


def test_ilqr_is_a_baseline_of_dock_and_reverse() -> None:
    settings = settings_from_kwargs(n_trailers=1)
    for env_id in (DOCK, "trailer_env/Reverse-v1", "trailer_env/Coast-v0"):
        policy = make_baseline("ilqr", settings, env_id)
        env = gym.make(env_id, n_trailers=1)
        obs, _ = env.reset(seed=50000)
        first = policy(obs[None])
        again = make_baseline("ilqr", settings, env_id)(obs[None])
        assert first.shape == (1, 1) and first.dtype == np.float32
        assert -1.0 <= float(first[0, 0]) <= 1.0
        assert first.tobytes() == again.tobytes()
    with pytest.raises(ValueError, match="ilqr"):
        make_baseline("ilqr", settings, "trailer_env/Heading-v0")


def test_bad_input_raises() -> None:
    settings = settings_from_kwargs(n_trailers=1)
    with pytest.raises(ValueError, match="horizon"):
        ILQRConfig(horizon=0)
    with pytest.raises(TypeError, match="iterations"):
        ILQRConfig(iterations=1.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="alphas"):
        ILQRConfig(alphas=())
    with pytest.raises(TypeError, match="reuse"):
        ILQRConfig(reuse="yes")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="central"):
        ILQRConfig(central=1)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="state_step"):
        ILQRConfig(state_step=0.0)
    with pytest.raises(ValueError, match="barrier"):
        CostWeights(barrier=-1.0)
    with pytest.raises(TypeError, match="weights"):
        SceneCost(DockCore, settings, {"angle": 1.0})  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="planar"):
        ILQRPlanner(ReverseV1Core, settings_from_kwargs(action_mode="planar"), 1)
    with pytest.raises(TypeError, match="batch_size"):
        ILQRPlanner(ReverseV1Core, settings, 1.0)  # type: ignore[arg-type]
    planner = ILQRPlanner(DockCore, settings, 1, ILQRConfig(horizon=5, iterations=1))
    core = reset_core(DockCore, 1, [50000])
    with pytest.raises(ValueError, match="target"):
        planner.plan(core.z, core.act)
    with pytest.raises(ValueError, match="columns"):
        planner.plan(core.z[:, :3], core.act, task_of(core))
    with pytest.raises(ValueError, match="states"):
        planner.plan(core.z, core.act[:, :4], task_of(core))
    bad = core.z.copy()
    bad[0, 1] = np.nan
    with pytest.raises(ValueError, match="finite"):
        planner.plan(bad, core.act, task_of(core))
