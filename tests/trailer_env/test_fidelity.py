"""Fidelity: the auto substep rule (accuracy and stability), fixed substeps, the registry."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from dynamics import AdaptiveStepper, ConvoyParams, Stepper
from tests.trailer_env.helpers import make
from trailer_env.core import ConvoyCore
from trailer_env.fidelity import AdaptiveIntegrator, Fidelity
from trailer_env.scenes import CoastCore, DockCore, HeadingCore, ReverseCore
from trailer_env.settings import EnvSettings, settings_from_kwargs
from trailer_env.substeps import (
    ERROR_CONSTANT,
    STABILITY_FRACTION,
    auto_substeps,
    cart_rate_coefficient,
    chain_growth,
    stability_limit,
)

SCENE_CORES = (ReverseCore, CoastCore, HeadingCore, DockCore)


def substeps_for(
    fidelity: Fidelity, params: ConvoyParams, z: np.ndarray, act: np.ndarray, dt: float = 0.05
) -> np.ndarray:
    counts = np.zeros(z.shape[0], dtype=np.int64)
    auto_substeps(z, act, fidelity.auto_settings(params, dt, False), counts)
    return counts


def rail_act(params: ConvoyParams, rows: int) -> np.ndarray:
    act = np.zeros((rows, 6))
    act[:, 0] = params.b
    return act


def step_error(
    params: ConvoyParams, z: np.ndarray, act: np.ndarray, dt: float, z_step: np.ndarray
) -> np.ndarray:
    """The documented error of one control step against a DOPRI5 reference at 1e-12."""
    reference, reference_act = z.copy(), act.copy()
    AdaptiveStepper(params, rtol=1e-12, atol=1e-12).step(
        reference, reference_act, dt, np.zeros(z.shape[0])
    )
    n, l = params.n_trailers, params.l
    mass_speed = np.abs(act[:, 2]) + np.abs(act[:, 3])
    mass_speed += dt * (np.abs(act[:, 4]) + np.abs(act[:, 5]))
    scale = np.maximum.reduce([np.abs(z[:, 0]), l * np.abs(z[:, 1]), mass_speed])
    delta = z_step - reference
    error = np.maximum(np.abs(delta[:, 0]), l * np.abs(delta[:, 1])) / scale
    if n:
        error = np.maximum(error, np.abs(delta[:, 2 : 2 + n]).max(axis=1))
    return error


def scene_samples(
    n: int, action_mode: str = "servo", rows: int = 8, steps: int = 40, seed: int = 0
) -> tuple[EnvSettings, np.ndarray, np.ndarray]:
    """States of every scene under random held actions, with the accelerations of the next step."""
    settings = settings_from_kwargs(n_trailers=n, action_mode=action_mode)
    rng = np.random.default_rng(seed)
    states, mass_states = [], []
    for core_class in SCENE_CORES:
        core = core_class(settings, rows)
        core.reset_rows(np.arange(rows), [np.random.default_rng(seed + i) for i in range(rows)])
        action = rng.uniform(-1.0, 1.0, (rows, settings.action_dim))
        for step in range(steps):
            change = rng.random(rows) < 0.2
            action[change] = rng.uniform(-1.0, 1.0, (int(change.sum()), settings.action_dim))
            before = core.z[:, : n + 2].copy()
            core.step(action)
            if step % 4 == 3:
                # The accelerations the step held: the actuator's, as the core applied them.
                states.append(before)
                mass_states.append(core.step_state.act_backup.copy())
            done = np.flatnonzero(core.terminated)
            if done.size:
                seeds = rng.integers(1 << 30, size=done.size)
                core.reset_rows(done, [np.random.default_rng(int(seed)) for seed in seeds])
    return settings, np.concatenate(states), np.concatenate(mass_states)


# --------------------------------------------------------------------------- the rule


def test_auto_rule_matches_its_formula() -> None:
    params = ConvoyParams(n_trailers=3)
    fidelity = Fidelity(tolerance=1e-6, max_substeps=8)
    dt = 0.05
    z = np.zeros((6, 5))
    z[:, 0] = [0.0, 1.0, 4.0, 1000.0, 1e5, np.nan]
    z[1, 1] = 0.1
    act = rail_act(params, 6)
    counts = substeps_for(fidelity, params, z, act, dt)
    speed_rate = max(1.0 / params.l, cart_rate_coefficient(params, planar=False))
    x_plain = dt * np.maximum(np.abs(z[:, 0]) * speed_rate, np.abs(z[:, 1]))
    x = chain_growth(3) * x_plain
    accurate = np.minimum(np.ceil((ERROR_CONSTANT * x**5 / 1e-6) ** 0.25), 8)
    stable = np.ceil(x_plain / (STABILITY_FRACTION * stability_limit(3)))
    expected = np.maximum(np.maximum(accurate, stable), 1)
    assert counts[:5].tolist() == expected[:5].astype(int).tolist()
    # At rest one substep; the cap holds for accuracy, stability overrides it; NaN -> 1.
    assert counts[0] == 1 and counts[3] > 8 and counts[4] == expected[4] > 1000
    assert counts[5] == 1
    # Where the cap does not bind the estimate is within the tolerance.
    k = counts[1:3]
    assert np.all(ERROR_CONSTANT * k * (x[1:3] / k) ** 5 <= 1e-6)


def test_the_cart_rate_counts_the_mass_as_part_of_the_cart() -> None:
    params = ConvoyParams()
    rail = cart_rate_coefficient(params, planar=False)
    assert rail == pytest.approx(
        (params.M * params.a + params.mu * params.b) / (params.I0 + params.mu * params.b**2)
    )
    grid = np.linspace(params.b - params.s_max, params.b + params.s_max, 2001)
    sampled = np.abs(params.M * params.a + params.mu * grid) / (params.I0 + params.mu * grid**2)
    assert cart_rate_coefficient(params, planar=True) == pytest.approx(sampled.max(), rel=1e-6)
    # A long hitch leaves the cart's eigenvalue in charge: substeps stop shrinking with l.
    z = np.array([[20.0, 0.0, 0.0, 0.0]])
    long_hitch = params.replace(l=100.0)
    fidelity = Fidelity()
    assert (
        substeps_for(fidelity, long_hitch, z, rail_act(long_hitch, 1))[0]
        == substeps_for(fidelity, params.replace(l=1.0 / rail), z, rail_act(params, 1))[0]
    )


def test_substeps_grow_with_speed_shrink_with_hitch_length_and_count_the_mass() -> None:
    fidelity = Fidelity()
    params = ConvoyParams(n_trailers=3)
    speeds = np.geomspace(0.01, 2000.0, 60)
    z = np.zeros((speeds.size, 5))
    z[:, 0] = -speeds
    counts = substeps_for(fidelity, params, z, rail_act(params, speeds.size))
    assert np.all(np.diff(counts) >= 0) and counts[0] == 1 and counts[-1] > 64
    # Scene speeds (|u| <= 1.5 m/s) with the mass at rest take one substep at n = 3.
    assert np.all(counts[speeds <= 1.5] == 1)
    by_length = [
        substeps_for(fidelity, params.replace(l=length, J=0.0), z[40:41], rail_act(params, 1))[0]
        for length in (0.1, 0.25, 0.5, 1.0)
    ]
    assert by_length == sorted(by_length, reverse=True) and by_length[0] > by_length[-1]
    # The mass moving fast on a convoy at rest asks for more than one substep.
    act = rail_act(params, 2)
    act[1, 3], act[1, 5] = 2.8, 4.0
    assert substeps_for(Fidelity(tolerance=1e-6), params, np.zeros((2, 5)), act).tolist()[0] == 1
    assert substeps_for(Fidelity(tolerance=1e-6), params, np.zeros((2, 5)), act)[1] > 1
    # More trailers, more substeps at the same speed (the chain factor g(n)).
    long_convoy = params.replace(n_trailers=32)
    reversing = np.zeros((1, 34))
    reversing[0, 0] = -1.0
    assert substeps_for(fidelity, long_convoy, reversing, rail_act(long_convoy, 1))[0] > 1


# At h |u| / l = 100 the max_substeps cap binds by design (stability decides): warned.
@pytest.mark.filterwarnings("ignore::trailer_env.fidelity.AccuracyWarning")
@pytest.mark.parametrize("n", [1, 3, 8])
def test_no_non_finite_state_across_a_sweep_of_dimensionless_speeds(n: int) -> None:
    """h |u| / l from 0.01 to 100 (initial speeds scaled), random actions, default fidelity."""
    settings = settings_from_kwargs(n_trailers=n)
    rng = np.random.default_rng(n)
    for core_class in SCENE_CORES:
        for x in (0.01, 0.1, 1.0, 3.0, 10.0, 30.0, 100.0):
            core = core_class(settings, 8)

            def start(rows: np.ndarray, core: ConvoyCore = core, x: float = x) -> None:
                seeds = rng.integers(1 << 30, size=rows.size)
                core.reset_rows(rows, [np.random.default_rng(int(seed)) for seed in seeds])
                factor = x * settings.params.l / (settings.dt * np.abs(core.z[rows, 0]))
                core.z[rows, :2] *= factor[:, None]
                core.refresh(rows)

            start(np.arange(8))
            for _ in range(50):
                core.step(rng.uniform(-1.0, 1.0, (8, 1)))
                assert np.all(np.isfinite(core.z))
                done = np.flatnonzero(core.terminated)
                if done.size:
                    start(done)


@pytest.mark.parametrize(("n", "action_mode"), [(1, "servo"), (3, "planar"), (8, "servo")])
def test_error_of_one_control_step_stays_within_the_tolerance(n: int, action_mode: str) -> None:
    """Scene states with speeds scaled to h |u| / l = 0.01 .. 100, against DOPRI5 at 1e-12."""
    settings, z0, act_all = scene_samples(n, action_mode)
    params, dt = settings.params, settings.dt
    planar = action_mode == "planar"
    # Fast rows take many substeps (about 3000 per row at x = 100, tolerance 1e-3): fewer rows.
    cases = {0.01: (1e-3, 1e-5, 1e-7), 0.1: (1e-3, 1e-5, 1e-7), 1.0: (1e-3, 1e-5, 1e-7),
             10.0: (1e-3, 1e-5), 100.0: (1e-3,)}  # fmt: skip
    for x, tolerances in cases.items():
        rows = slice(None) if x < 100.0 else slice(None, None, 4)
        z = z0[rows].copy()
        z[:, :2] *= (x * params.l / dt / np.abs(z[:, 0]))[:, None]
        act = act_all[rows]
        for tolerance in tolerances:
            fidelity = Fidelity(tolerance=tolerance, max_substeps=1_000_000)
            counts = np.zeros(z.shape[0], dtype=np.int64)
            auto_substeps(z, act, fidelity.auto_settings(params, dt, planar), counts)
            stepped, stepped_act = z.copy(), act.copy()
            Stepper(params).step(stepped, stepped_act, dt, counts)
            error = step_error(params, z, act, dt, stepped)
            assert error.max() <= tolerance, (x, tolerance, error.max())


def test_default_fidelity_takes_one_substep_in_the_two_trailer_scenes() -> None:
    for name in ("Reverse", "Coast", "Heading", "Dock"):
        envs = gym.make_vec(
            f"trailer_env/{name}-v0", num_envs=32, vectorization_mode="vector_entry_point"
        )
        envs.reset(seed=0)
        envs.action_space.seed(0)
        for _ in range(40):
            envs.step(envs.action_space.sample())
            assert np.all(envs.unwrapped.core.substeps == 1)


# --------------------------------------------------------------------------- envs


def test_env_uses_auto_or_fixed_substeps() -> None:
    env = make("Reverse", n_trailers=8, fidelity={"substeps": "auto", "tolerance": 1e-8})
    env.reset(seed=0)
    env.step(np.zeros(1, dtype=np.float32))
    assert env.unwrapped.core.substeps[0] > 1
    fixed = make("Reverse", fidelity=7)
    fixed.reset(seed=0)
    fixed.step(np.zeros(1, dtype=np.float32))
    assert fixed.unwrapped.core.substeps[0] == 7


def test_finer_fidelity_converges() -> None:
    """The same episode at tolerance 1e-3 and 1e-10 agrees to the coarser tolerance's accuracy."""
    results = []
    for tolerance in (1e-3, 1e-10):
        env = make("Reverse", fidelity={"tolerance": tolerance})
        env.reset(seed=3)
        for _ in range(40):
            env.step(np.array([0.3], dtype=np.float32))
        results.append(env.unwrapped.core.z[0].copy())
    assert np.max(np.abs(results[0] - results[1])) < 1e-4


def test_dopri5_is_registered_and_meets_its_tolerance() -> None:
    loose = make("Reverse", fidelity="dopri5")
    assert isinstance(loose.unwrapped.core._integrator, AdaptiveIntegrator)
    assert loose.unwrapped.settings.fidelity.substeps == "auto"
    assert not loose.unwrapped.settings.fidelity.auto
    tight = make("Reverse", fidelity={"integrator": "dopri5", "tolerance": 1e-10})
    rk4 = make("Reverse", fidelity={"tolerance": 1e-10})
    finals = []
    for env in (loose, tight, rk4):
        env.reset(seed=5)
        for _ in range(40):
            env.step(np.array([-0.4], dtype=np.float32))
        if env is not rk4:
            assert env.unwrapped.core.substeps[0] == 1  # adaptive: the count is not used
        finals.append(env.unwrapped.core.z[0].copy())
    assert np.max(np.abs(finals[1] - finals[2])) < 1e-7
    assert 0.0 < np.max(np.abs(finals[0] - finals[2])) < 1e-2
    # The vector env steps the same rows the same way.
    envs = gym.make_vec(
        "trailer_env/Reverse-v0",
        num_envs=3,
        vectorization_mode="vector_entry_point",
        fidelity={"integrator": "dopri5", "tolerance": 1e-6},
    )
    envs.reset(seed=0)
    envs.step(np.zeros((3, 1), dtype=np.float32))
    assert np.all(np.isfinite(envs.unwrapped.core.z))


def test_a_failing_adaptive_row_is_reported_as_diverged() -> None:
    params = ConvoyParams(n_trailers=1)
    integrator = AdaptiveIntegrator(params, False, 1e-6)
    integrator._stepper.max_steps = 20
    z = np.array([[100.0, 0.0, 0.1], [0.0, 0.0, 0.0]])
    integrator.step(z, rail_act(params, 2), 1.0, np.ones(2, dtype=np.int64))
    assert np.all(np.isnan(z[0])) and np.all(z[1] == 0.0)


@pytest.mark.parametrize(
    ("scene", "needs_pose"),
    [("Reverse", False), ("Coast", False), ("Heading", True), ("Dock", True)],
)
def test_poses_are_integrated_only_where_needed(scene: str, needs_pose: bool) -> None:
    """Dock needs the plane pose, Heading the cart's heading; rendering needs both."""
    assert make(scene).unwrapped.core.with_pose is needs_pose
    assert make(scene, render_mode="rgb_array").unwrapped.core.with_pose is True
    envs = gym.make_vec(
        f"trailer_env/{scene}-v0", num_envs=2, vectorization_mode="vector_entry_point"
    )
    assert envs.unwrapped.core.with_pose is needs_pose
    assert envs.unwrapped.core.z.shape[1] == 2 + 2 + (3 if needs_pose else 0)


def test_tolerance_is_validated() -> None:
    for bad in (0.0, 0.1, -1e-6, float("nan")):
        with pytest.raises(ValueError, match=r"fidelity\.tolerance"):
            Fidelity(tolerance=bad)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"fidelity\.tolerance"):
        Fidelity(tolerance="tight")  # type: ignore[arg-type]
    assert Fidelity().tolerance == 1e-4


def test_energy_preserving_integrator_conserves_energy_without_the_mass() -> None:
    env = make("Coast", mu=0.0, fidelity="rk4-energy")
    _, info = env.reset(seed=1)
    energies = [info["energy"]]
    for _ in range(100):
        _, _, terminated, _, info = env.step(np.array([0.7], dtype=np.float32))
        energies.append(info["energy"])
        if terminated:
            break
    assert np.ptp(energies) < 1e-12 * energies[0]


def test_integrator_names_and_coercion() -> None:
    params = ConvoyParams(mu=0.0)
    kinds = {
        name: (
            Fidelity(integrator=name).fused,
            Fidelity(integrator=name).preserve_energy,
            type(Fidelity(integrator=name).outer_integrator(params, False)),
        )
        for name in ("rk4", "rk4-energy", "dopri5")
    }
    assert kinds == {
        "rk4": (True, False, type(None)),
        "rk4-energy": (True, True, type(None)),
        "dopri5": (False, False, AdaptiveIntegrator),
    }
    with pytest.raises(ValueError, match="mu = 0"):
        Fidelity(integrator="rk4-energy").check_params(ConvoyParams(mu=0.1))
    with pytest.raises(ValueError, match=r"fidelity\.integrator"):
        Fidelity(integrator="not-registered")
    assert Fidelity.coerce(None) == Fidelity()
    assert Fidelity.coerce("auto").auto
    assert Fidelity.coerce(4).substeps == 4
