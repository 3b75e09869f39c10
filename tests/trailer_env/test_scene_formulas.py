"""Each scene's reward and termination are written once: the fused (RK4) and unfused
(dopri5) steps call the same compiled formulas and agree on the same state."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from trailer_env.core import ConvoyCore, ShapedCore
from trailer_env.kernels import StepConfig, StepOutputs, StepState
from trailer_env.scenes import CoastCore, HeadingCore, ReverseCore, ReverseV1Core
from trailer_env.scenes.coast import CoastScene
from trailer_env.scenes.reverse import ReverseScene
from trailer_env.settings import settings_from_kwargs
from trailer_env.shaping import shaped_rewards

ROWS = 12


def _core(core_class: type[ConvoyCore], fidelity: str, seed: int = 0) -> ConvoyCore:
    core = core_class(settings_from_kwargs(n_trailers=2, fidelity=fidelity), ROWS)
    core.reset_rows(np.arange(ROWS), [np.random.default_rng(seed + i) for i in range(ROWS)])
    return core


def _copy_state(source: ConvoyCore, target: ConvoyCore) -> None:
    """Give ``target`` the state, mass and episode bookkeeping of ``source``."""
    target.z[:] = source.z
    target.act[:] = source.act
    target.refresh()
    if isinstance(source, ShapedCore) and isinstance(target, ShapedCore):
        target.previous_potential[:] = source.previous_potential


def _recount(core: ConvoyCore, calls: list[int]) -> None:
    outcome = type(core).scene_outcome

    def counting(*args: Any) -> None:
        calls.append(1)
        outcome(*args)

    core.scene_outcome = counting  # type: ignore[method-assign]


@pytest.mark.parametrize("core_class", [ReverseCore, ReverseV1Core, CoastCore])
def test_fused_and_unfused_steps_share_the_compiled_outcome(
    core_class: type[ConvoyCore],
) -> None:
    fused = _core(core_class, "rk4")
    unfused = _core(core_class, "dopri5")
    assert fused.settings.fidelity.fused and not unfused.settings.fidelity.fused
    calls: list[int] = []
    _recount(unfused, calls)
    rng = np.random.default_rng(1)
    for _ in range(25):
        action = rng.uniform(-1.0, 1.0, (ROWS, 1))
        _copy_state(fused, unfused)  # the same start for both
        shaped = isinstance(fused, ShapedCore) and isinstance(unfused, ShapedCore)
        previous = fused.previous_potential.copy() if shaped else None  # type: ignore[attr-defined]
        fused.step(action)
        unfused.step(action)
        for core in (fused, unfused):
            # Each step's results are the outcome function's on the state it reached.
            results = (core.reward.copy(), core.terminated.copy(), core.success.copy())
            if previous is not None:
                core.previous_potential[:] = previous  # type: ignore[attr-defined]
            type(core).scene_outcome(
                core._all_rows, core.kernel_args.outputs_tuple, core._scene_tuple()
            )
            for array, result in zip(
                (core.reward, core.terminated, core.success), results, strict=True
            ):
                np.testing.assert_array_equal(array, result)
        # The integrators land within their tolerance of each other: so do the rewards.
        np.testing.assert_allclose(unfused.reward, fused.reward, rtol=0, atol=1e-4)
        np.testing.assert_array_equal(unfused.terminated, fused.terminated)
        done = np.flatnonzero(fused.terminated)
        if done.size:
            fused.reset_rows(done, [np.random.default_rng(100 + int(i)) for i in done])
    assert len(calls) == 25  # one outcome call per unfused step, for the whole batch


def test_reverse_formulas_by_hand_on_a_batch() -> None:
    core = _core(ReverseCore, "rk4")
    rows = np.arange(ROWS)
    core.z[:, 0] = np.linspace(-1.0, 0.5, ROWS)  # the last rows stopped reversing
    core.z[:, 1] = np.linspace(-2.0, 2.0, ROWS)
    core.z[:, 2:4] = np.linspace(-1.4, 1.4, 2 * ROWS).reshape(ROWS, 2)
    core.refresh()
    core.jackknifed[3] = True
    scene = core._scene_arguments()
    assert isinstance(scene, ReverseScene) and scene.z is core.z and scene.reward is core.reward
    type(core).scene_outcome(rows, core.kernel_args.outputs_tuple, tuple(scene))
    failed = core.jackknifed | (core.z[:, 0] >= 0.0)
    omega = core.z[:, 1]
    expected = (
        np.cos(core.z[:, 2:4]).mean(axis=1)
        - 0.1 * np.minimum(omega**2, 1.0)
        - 0.5 * core.cost
        - 10.0 * failed
    )
    np.testing.assert_allclose(core.reward, expected, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(core.terminated, failed)
    np.testing.assert_array_equal(core.success, ~failed)
    np.testing.assert_array_equal(core._is_success(), ~failed)  # the reset's flag, same formula


def test_the_named_tuples_hold_the_core_arrays() -> None:
    core = _core(CoastCore, "rk4")
    assert isinstance(core.step_config, StepConfig) and core.kernel_args.config_tuple == tuple(
        core.step_config
    )
    assert isinstance(core.step_state, StepState) and core.step_state.z is core.z
    assert isinstance(core.step_outputs, StepOutputs)
    assert core.step_outputs.hitch_trig is core.hitch_trig and core.step_outputs.cost is core.cost
    assert core.step_config.n == 2 and core.step_config.dt == core.settings.dt
    scene = core._scene_arguments()
    assert isinstance(scene, CoastScene) and scene.previous is core.previous_potential
    np.testing.assert_array_equal(scene.penalties, [0.01, 0.05, 10.0, 20.0, 10.0])


def test_shaped_rewards_is_the_documented_formula_bit_for_bit() -> None:
    rng = np.random.default_rng(3)
    count = 64
    potential, previous, cost = rng.normal(size=count), rng.normal(size=count), rng.random(count)
    success, jackknifed, failed = rng.random((3, count)) < 0.3
    core = HeadingCore(settings_from_kwargs(n_trailers=1), 1)
    penalties = core.shaping_penalties
    out = np.empty(count)
    shaped_rewards(potential, previous, cost, success, jackknifed, failed, penalties, out)
    expected = (
        potential
        - previous
        - core.time_penalty
        - core.band_penalty * cost
        + core.success_bonus * success
        - core.fold_penalty * jackknifed
        - core.failure_penalty * failed
    )
    np.testing.assert_array_equal(out, expected)


@pytest.mark.parametrize("env_id", ["trailer_env/Reverse-v1", "trailer_env/Coast-v0"])
def test_the_singular_margin_never_looks_at_the_last_hitch(env_id: str) -> None:
    import gymnasium as gym

    near_right_angle = 1.5  # rad: |cos| = 0.07, well inside the band, short of folding
    with gym.make(env_id, n_trailers=1) as env:
        _, info = env.reset(seed=0, options={"state": [-1.0, 0.0, near_right_angle]})
        assert info["singular_margin"] == 1.0 and info["cost"] == 0.0
    with gym.make(env_id, n_trailers=2) as env:
        _, info = env.reset(seed=0, options={"state": [-1.0, 0.0, 0.0, near_right_angle]})
        assert info["singular_margin"] == 1.0
        _, info = env.reset(seed=0, options={"state": [-1.0, 0.0, near_right_angle, 0.0]})
        assert info["singular_margin"] == pytest.approx(np.cos(near_right_angle), rel=1e-12)
        assert info["cost"] == 1.0
