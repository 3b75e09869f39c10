"""Fidelity: the auto substep rule, fixed substeps, the integrator registry."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics import ConvoyParams, Stepper
from tests.trailer_env.helpers import make
from trailer_env.fidelity import (
    Fidelity,
    IntegratorSpec,
    auto_substeps,
    integrator_names,
    register_integrator,
)


def test_auto_rule_picks_the_fewest_substeps_under_the_bound() -> None:
    z = np.array([[1.0, 0.0, 0.0], [-10.0, 0.0, 0.0], [0.1, 30.0, 0.0], [1e9, 0.0, 0.0]])
    out = np.zeros(4, dtype=np.int64)
    auto_substeps(z, 0.05, 0.5, 0.1, 64, out)
    # rate = max(|u| / l, |omega|): 2, 20, 30, huge -> ceil(0.05 * rate / 0.1), capped at 64.
    assert out.tolist() == [1, 10, 15, 64]
    h = 0.05 / out[:3]
    assert np.all(h * np.maximum(np.abs(z[:3, 0]) / 0.5, np.abs(z[:3, 1])) <= 0.1 + 1e-12)


def test_env_uses_auto_or_fixed_substeps() -> None:
    env = make("Reverse", fidelity={"substeps": "auto", "tolerance": 0.01})
    env.reset(seed=0)
    env.step(np.zeros(1, dtype=np.float32))
    speed = abs(env.unwrapped.core.z[0, 0])
    # |u| ~ 1 m/s, l = 1: 0.05 * |u| / 0.01 -> about 5 substeps.
    assert env.unwrapped.core.substeps[0] >= int(np.ceil(0.05 * speed / 0.01)) - 1
    fixed = make("Reverse", fidelity=7)
    fixed.reset(seed=0)
    fixed.step(np.zeros(1, dtype=np.float32))
    assert fixed.unwrapped.core.substeps[0] == 7


def test_finer_fidelity_converges() -> None:
    """The same episode at tolerance 0.1 and 0.005 agrees to RK4 accuracy."""
    results = []
    for tolerance in (0.1, 0.005):
        env = make("Reverse", fidelity={"tolerance": tolerance})
        env.reset(seed=3)
        for _ in range(40):
            env.step(np.array([0.3], dtype=np.float32))
        results.append(env.unwrapped.core.z[0].copy())
    assert np.max(np.abs(results[0] - results[1])) < 1e-5


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


def test_another_integrator_can_be_plugged_in() -> None:
    calls = []

    class Counting(Stepper):
        def step(self, z, act, dt, substeps, target_energy=None):  # type: ignore[no-untyped-def]
            calls.append(z.shape[0])
            super().step(z, act, dt, substeps)

    register_integrator(
        "counting-rk4",
        IntegratorSpec(lambda params, with_pose, _: Counting(params, with_pose=with_pose)),
    )
    assert "counting-rk4" in integrator_names()
    env = make("Reverse", fidelity="counting-rk4")
    env.reset(seed=0)
    env.step(np.zeros(1, dtype=np.float32))
    assert calls == [1]
    with pytest.raises(ValueError, match=r"fidelity\.integrator"):
        Fidelity(integrator="not-registered")
    assert Fidelity.coerce(None) == Fidelity()
    assert Fidelity.coerce("auto").auto
    assert Fidelity.coerce(4).substeps == 4
    assert isinstance(Fidelity().make_integrator(ConvoyParams(), False), Stepper)
