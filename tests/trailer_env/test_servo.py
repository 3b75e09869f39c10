"""The actuator: the end-of-rail guard, the servo, the action modes."""

from __future__ import annotations

import numpy as np
import pytest

from tests.trailer_env.helpers import make
from trailer_env.actuator import guard_accel, servo_accel

S_MAX = 0.5
DT = 0.05


def _admissible(rng: np.random.Generator, accel_max: float) -> tuple[float, float]:
    """A rail state from which the mass can still stop before either end."""
    s = rng.uniform(-S_MAX, S_MAX)
    v_up = np.sqrt(2 * accel_max * (S_MAX - s))
    v_down = np.sqrt(2 * accel_max * (S_MAX + s))
    if rng.random() < 0.2:  # on the braking curve itself
        return s, (v_up if rng.random() < 0.5 else -v_down) * (1 - 1e-12)
    return s, rng.uniform(-v_down, v_up)


@pytest.mark.parametrize("accel_max", [0.5, 4.0, S_MAX / DT**2])
def test_guard_keeps_the_mass_on_the_rail_at_every_instant(
    rng: np.random.Generator, accel_max: float
) -> None:
    times = np.linspace(0.0, DT, 101)
    for _ in range(3000):
        s, v = _admissible(rng, accel_max)
        wanted = rng.uniform(-3 * accel_max, 3 * accel_max)
        a = guard_accel(wanted, s, v, S_MAX, accel_max, DT)
        assert -accel_max <= a <= accel_max
        path = s + v * times + 0.5 * a * times**2
        assert np.max(np.abs(path)) <= S_MAX * (1 + 1e-12)
        s1, v1 = path[-1], v + a * DT
        # The invariant carries over: it can still stop before either end.
        assert s1 + max(v1, 0.0) ** 2 / (2 * accel_max) <= S_MAX * (1 + 1e-9)
        assert s1 - max(-v1, 0.0) ** 2 / (2 * accel_max) >= -S_MAX * (1 + 1e-9)


def test_guard_leaves_safe_accelerations_alone() -> None:
    assert guard_accel(1.0, 0.0, 0.0, S_MAX, 4.0, DT) == 1.0
    assert guard_accel(-9.0, 0.0, 0.0, S_MAX, 4.0, DT) == -4.0
    # Rushing at the upper end: full braking.
    v = np.sqrt(2 * 4.0 * 0.1)
    assert guard_accel(4.0, S_MAX - 0.1, v, S_MAX, 4.0, DT) == pytest.approx(-4.0, rel=1e-6)


def test_servo_reaches_the_target_without_overshoot() -> None:
    s = v = 0.0
    trace = []
    for _ in range(60):
        a = servo_accel(0.4, s, v, S_MAX, 4.0, DT, 5.0)
        s, v = s + v * DT + 0.5 * a * DT**2, v + a * DT
        trace.append(s)
    assert trace[-1] == pytest.approx(0.4, abs=1e-4)
    assert max(trace) < 0.4 + 0.01


@pytest.mark.parametrize("mode", ["servo", "accel", "planar"])
def test_the_mass_never_leaves_its_rail_in_an_episode(rng: np.random.Generator, mode: str) -> None:
    env = make("Coast", action_mode=mode, n_trailers=1)
    env.reset(seed=2)
    core = env.unwrapped.core
    b = core.params.b
    for _ in range(300):
        action = rng.choice([-5.0, -1.0, 1.0, 5.0], size=env.action_space.shape).astype(np.float32)
        _, _, terminated, truncated, _ = env.step(action)
        assert abs(core.act[0, 1]) <= S_MAX
        assert abs(core.act[0, 0] - b) <= (S_MAX if mode == "planar" else 0.0)
        if terminated or truncated:
            env.reset()


def test_out_of_range_actions_are_clipped() -> None:
    results = []
    for action in (1.0, 7.5):
        env = make("Reverse", action_mode="accel")
        env.reset(seed=5)
        for _ in range(5):
            obs, *_ = env.step(np.array([action], dtype=np.float32))
        results.append(obs)
    np.testing.assert_array_equal(results[0], results[1])


def test_servo_target_sets_the_steady_position() -> None:
    env = make("Coast", n_trailers=0)
    env.reset(seed=0)
    for _ in range(40):
        obs, *_ = env.step(np.array([-0.6], dtype=np.float32))
    # Observation index 2n+2 = 2 is s / s_max, index 3 the normalised velocity.
    assert obs[2] == pytest.approx(-0.6, abs=1e-3)
    assert abs(obs[3]) < 1e-3
