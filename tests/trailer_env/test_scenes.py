"""The single environments: API checks, observation layout, rewards and terminations by hand."""

from __future__ import annotations

import math
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import trailer_env
from dynamics import ConvoyParams, energy, is_jackknifed, rhs, singular_margin
from tests.trailer_env.helpers import SCENE_IDS, make
from trailer_env.registry import env_id_of
from trailer_env.scenes import SCENE_ENVS
from trailer_env.vector import ConvoyVectorEnv


@pytest.mark.parametrize("env_id", SCENE_IDS)
@pytest.mark.parametrize("n", [0, 1, 3])
def test_gymnasium_and_sb3_checkers_pass(env_id: str, n: int) -> None:
    with warnings.catch_warnings():
        # u and omega are unbounded by nature: the checkers' note about infinite bounds is expected.
        warnings.filterwarnings("ignore", message=".*infinity.*")
        warnings.filterwarnings("ignore", message=".*XDG_RUNTIME_DIR.*")
        env = gym.make(env_id, n_trailers=n)
        check_env(env.unwrapped, skip_render_check=True)
        sb3_check_env(gym.make(env_id, n_trailers=n), warn=True)
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert set(info) >= {"cost", "singular_margin", "energy", "actuator_work", "is_success"}
    assert all(type(value) in (float, bool) for value in info.values())


@pytest.mark.parametrize("mode", ["accel", "planar"])
def test_other_action_modes_pass_the_checker(mode: str) -> None:
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*infinity.*")
        env = make("Dock", action_mode=mode)
        check_env(env.unwrapped, skip_render_check=True)
    assert env.action_space.shape == ((2,) if mode == "planar" else (1,))
    assert env.observation_space.shape == (2 * 2 + (6 if mode == "planar" else 4) + 4,)


def test_ids_are_registered_with_both_entry_points() -> None:
    """Every scene of the table is registered as its core declares it (read from the
    table, so that a new scene needs no edit here)."""
    assert list(trailer_env.ENVIRONMENTS) == [env_id_of(env) for env in SCENE_ENVS]
    assert len(set(trailer_env.ENVIRONMENTS)) == len(SCENE_ENVS) >= 1
    for env_id, env_class in trailer_env.ENVIRONMENTS.items():
        core = env_class.core_class
        assert env_id == f"trailer_env/{core.scene}-v{core.version}"
        spec = gym.spec(env_id)
        assert spec.max_episode_steps == core.max_episode_steps >= 1
        assert spec.entry_point == f"{env_class.__module__}:{env_class.__name__}"
        assert env_class.__module__.startswith("trailer_env.scenes.")
        envs = gym.make_vec(spec.id, num_envs=2, vectorization_mode="vector_entry_point")
        assert isinstance(envs.unwrapped, ConvoyVectorEnv)
        assert envs.unwrapped.core_class is core
        assert envs.unwrapped.max_episode_steps == core.max_episode_steps
    env = gym.make("trailer_env:trailer_env/Reverse-v0")
    assert type(env.unwrapped).__name__ == "ReverseEnv"
    assert gym.spec("trailer_env/Reverse-v1").entry_point == (
        "trailer_env.scenes.reverse_v1:ReverseV1Env"
    )


def test_common_observation_layout() -> None:
    env = make("Reverse", n_trailers=3)
    env.reset(seed=0)
    z = [-0.9, 0.2, 0.1, -0.3, 1.2]
    obs = env.unwrapped.set_state(z, s=0.25, s_dot=-0.5)
    settings = env.unwrapped.settings
    np.testing.assert_allclose(obs[:2], z[:2], rtol=1e-6)
    np.testing.assert_allclose(obs[2:5], np.sin(z[2:]), rtol=1e-6)
    np.testing.assert_allclose(obs[5:8], np.cos(z[2:]), rtol=1e-6)
    assert obs[8] == pytest.approx(0.25 / 0.5)
    assert obs[9] == pytest.approx(-0.5 / settings.rail_speed_max)
    assert obs.shape == (10,) and obs.dtype == np.float32


@pytest.mark.parametrize("n", [0, 1, 2, 4])
def test_info_matches_dynamics(rng: np.random.Generator, n: int) -> None:
    env = make("Coast", n_trailers=n)
    env.reset(seed=0)
    params: ConvoyParams = env.unwrapped.settings.params
    for _ in range(10):
        z = np.concatenate([[rng.uniform(-1, 1), rng.uniform(-1, 1)], rng.uniform(-1.6, 1.6, n)])
        env.unwrapped.set_state(z, s=0.1, s_dot=0.2)
        _, _, _, _, info = env.step(np.array([0.0], dtype=np.float32))
        core = env.unwrapped.core
        state = core.z[0, : n + 2]
        margin = float(singular_margin(state[2:]))
        assert info["singular_margin"] == pytest.approx(margin)
        assert info["cost"] == (1.0 if margin < 0.3 else 0.0)
        assert info["jackknifed"] == bool(is_jackknifed(state[2:]))
        assert info["energy"] == pytest.approx(
            float(energy(params, state, core.act[0, 1], core.act[0, 3]))
        )


def test_actuator_work_is_the_energy_change() -> None:
    env = make("Reverse", n_trailers=2)
    _, info0 = env.reset(seed=4)
    assert info0["actuator_work"] == 0.0
    for k in range(30):
        _, _, _, _, info = env.step(np.array([math.sin(k / 3)], dtype=np.float32))
    assert info["actuator_work"] == pytest.approx(info["energy"] - info0["energy"])
    assert abs(info["actuator_work"]) > 1e-4


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_actions_raise_and_change_nothing(bad: float) -> None:
    env = make("Reverse")
    env.reset(seed=0)
    before = env.unwrapped.core.z.copy()
    with pytest.raises(ValueError, match="non-finite"):
        env.step(np.array([bad], dtype=np.float32))
    np.testing.assert_array_equal(env.unwrapped.core.z, before)
    assert np.all(np.isfinite(env.unwrapped.core.z))
    env.step(np.array([0.0], dtype=np.float32))  # still usable


def test_malformed_actions_raise() -> None:
    env = make("Reverse")
    env.reset(seed=0)
    with pytest.raises(ValueError):
        env.step(np.zeros(3, dtype=np.float32))
    with pytest.raises(TypeError):
        env.step("left")


def test_state_stays_finite_under_extreme_actions(rng: np.random.Generator) -> None:
    env = make("Reverse", n_trailers=3, action_mode="accel", fidelity=1)
    env.reset(seed=0)
    for _ in range(400):
        _, _, terminated, truncated, _ = env.step(
            rng.choice([-1e30, 1e30], size=1).astype(np.float32)
        )
        assert np.all(np.isfinite(env.unwrapped.core.z))
        if terminated or truncated:
            env.reset()


def test_set_state_validates() -> None:
    env = make("Reverse")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="length"):
        env.unwrapped.set_state([1.0, 0.0])
    with pytest.raises(ValueError, match="finite"):
        env.unwrapped.set_state([1.0, 0.0, np.nan, 0.0])
    with pytest.raises(ValueError, match="rail"):
        env.unwrapped.set_state([1.0, 0.0, 0.0, 0.0], s=0.49, s_dot=3.0)
    with pytest.raises(ValueError, match="unknown task"):
        env.unwrapped.set_state([1.0, 0.0, 0.0, 0.0], target_heading=1.0)


def test_pickled_env_continues_identically() -> None:
    env = make("Dock")
    env.reset(seed=8)
    for _ in range(5):
        env.step(np.array([0.4], dtype=np.float32))
    clone = pickle.loads(pickle.dumps(env))
    for _ in range(5):
        a = env.step(np.array([-0.2], dtype=np.float32))
        b = clone.step(np.array([-0.2], dtype=np.float32))
        np.testing.assert_array_equal(a[0], b[0])
        assert a[1] == b[1]


# --------------------------------------------------------------------------- per-scene tasks


def _step(env: gym.Env, action: float = 0.0) -> tuple[np.ndarray, float, bool, bool, dict]:
    return env.step(np.array([action], dtype=np.float32))


def test_reverse_reward_and_termination_by_hand() -> None:
    env = make("Reverse", n_trailers=2)
    env.reset(seed=0)
    # Straight, reversing, mass at rest: reward = mean cos(alpha) - 0.1 omega^2, no termination.
    env.unwrapped.set_state([-1.0, 0.0, 0.0, 0.0])
    _, reward, terminated, _, info = _step(env)
    assert reward == pytest.approx(1.0, abs=1e-4) and not terminated and info["is_success"]
    # Inside the singular band (|cos alpha_1| < 0.3), not folded: band penalty 0.5.
    env.unwrapped.set_state([-0.01, 0.0, 1.4, 0.0])
    _, reward, terminated, _, info = _step(env)
    alpha = env.unwrapped.core.z[0, 2:4]
    assert info["cost"] == 1.0 and not terminated
    assert reward == pytest.approx(np.mean(np.cos(alpha)) - 0.5, abs=1e-6)
    # Folded last trailer: terminated with the fold penalty.
    env.unwrapped.set_state([-1.0, 0.0, 0.0, 1.6])
    _, reward, terminated, _, info = _step(env)
    assert terminated and info["jackknifed"] and not info["is_success"]
    assert reward < -9.0
    # Stopping or driving forwards escapes the task: a failure, like a fold.
    env.reset(seed=0)
    env.unwrapped.set_state([1.0, 0.0, 0.0, 0.0])
    _, reward, terminated, _, info = _step(env)
    assert terminated and not info["is_success"] and not info["jackknifed"]
    assert reward == pytest.approx(1.0 - 10.0, abs=1e-4)


def test_coast_success_and_shaping_by_hand() -> None:
    env = make("Coast", n_trailers=2)
    env.reset(seed=0)
    env.unwrapped.set_state([1.0, 0.0, 0.01, -0.01])
    _, reward, terminated, _, info = _step(env)
    assert terminated and info["is_success"] and reward > 9.0
    # Forwards the convoy straightens by itself: the potential rises, shaping is positive.
    env.unwrapped.set_state([1.0, 0.0, 0.4, -0.3])
    _, reward, terminated, _, _ = _step(env)
    assert not terminated and 0.0 < reward < 1.0
    env.unwrapped.set_state([-1.0, 0.0, math.pi / 2 - 0.01, 0.0])  # reversing: it folds
    _, reward, terminated, _, info = _step(env)
    assert terminated and info["jackknifed"] and reward < -19.0


def test_heading_holds_then_succeeds_by_hand() -> None:
    env = make("Heading", n_trailers=1)
    env.reset(seed=0)
    # Already at the target heading (theta = 0.1), nothing moving: success after 20 steps held.
    obs = env.unwrapped.set_state([1.0, 0.0, 0.0, 0.0, 0.0, 0.1], target_heading=0.1)
    assert obs[-3] == pytest.approx(0.0, abs=1e-6) and obs[-2] == pytest.approx(1.0)
    for k in range(1, 21):
        obs, reward, terminated, _, info = _step(env)
        assert obs[-1] == pytest.approx(k / 20)
        assert terminated == (k == 20)
    assert info["is_success"] and reward > 9.0
    # Off target the heading error is observed, and the hold counter stays at zero.
    obs = env.unwrapped.set_state([1.0, 0.0, 0.0, 0.0, 0.0, 0.0], target_heading=-0.12)
    assert math.atan2(obs[-3], obs[-2]) == pytest.approx(-0.12, abs=1e-6)
    obs, _, terminated, _, _ = _step(env)
    assert obs[-1] == 0.0 and not terminated


def test_dock_success_miss_and_features_by_hand() -> None:
    env = make("Dock", n_trailers=2)
    env.reset(seed=0)
    # Straight convoy: cart at (0, 0) heading 0, last axle at (-2, 0). Dock 1 m behind it.
    obs = env.unwrapped.set_state([-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], target=(-3.0, 0.2, 0.0))
    np.testing.assert_allclose(obs[-4:], [1.0 / 5, -0.2 / 5, 0.0, 1.0], atol=1e-6)
    _, reward, terminated, _, _ = _step(env)
    assert not terminated and reward > 0.0  # approaching
    # On the dock: success.
    env.unwrapped.set_state([-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], target=(-2.05, 0.1, 0.05))
    _, reward, terminated, _, info = _step(env)
    assert terminated and info["is_success"] and reward > 9.0
    # Past the dock line by more than 0.5 m, 1 m to the side: missed.
    env.unwrapped.set_state([-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], target=(-1.0, 1.0, 0.0))
    _, reward, terminated, _, info = _step(env)
    assert terminated and not info["is_success"] and reward < -29.0


@pytest.mark.parametrize("scene", ["Reverse", "Coast", "Heading", "Dock"])
def test_starting_states_follow_the_documented_ranges(scene: str) -> None:
    env = make(scene, n_trailers=2)
    for seed in range(20):
        env.reset(seed=seed)
        z = env.unwrapped.core.z[0]
        assert 0.5 <= abs(z[0]) <= 1.5
        assert np.max(np.abs(z[2:4])) <= 0.5
        assert env.unwrapped.core.act[0, 1] == 0.0
        if scene in ("Reverse", "Dock"):
            assert z[0] < 0.0
        if scene == "Heading":
            assert 0.05 <= abs(env.unwrapped.core.target_heading[0]) <= 0.15


def test_actuator_work_is_the_integrated_actuator_power() -> None:
    """actuator_work = integral of F_rail s_dot, F_rail = mu (b w_dot + s_ddot + w u - w^2 s)."""
    dt = 0.005
    env = make("Coast", n_trailers=2, dt=dt, rail_accel_max=4.0)
    env.reset(seed=12)
    env.unwrapped.set_state([1.0, 0.2, 0.3, -0.2])
    core = env.unwrapped.core
    params = core.params

    def power(z: np.ndarray, s: float, s_dot: float, s_ddot: float) -> float:
        omega_dot = rhs(params, z, s, s_dot, s_ddot)[1]
        force = params.mu * (params.b * omega_dot + s_ddot + z[1] * z[0] - z[1] ** 2 * s)
        return float(force * s_dot)

    work = 0.0
    for k in range(300):
        before = (core.z[0].copy(), core.act[0, 1], core.act[0, 3])
        _, _, terminated, _, info = env.step(np.array([np.sin(k * dt * 6.0)], dtype=np.float32))
        s_ddot = core.act[0, 5]
        after = (core.z[0].copy(), core.act[0, 1], core.act[0, 3])
        work += 0.5 * dt * (power(*before, s_ddot) + power(*after, s_ddot))
        assert not terminated
    assert abs(work) > 1e-3
    assert info["actuator_work"] == pytest.approx(work, rel=1e-3)


@pytest.mark.parametrize("n", [0, 1, 3, 8])
def test_reverse_start_is_the_documented_uniform_draws(n: int) -> None:
    # One draw of n + 2 uniforms per reset gives, bit for bit, the numbers of drawing
    # u ~ -U(0.8, 1.2), omega ~ U(-0.05, 0.05), alpha ~ U(-0.05, 0.05)^n in that order.
    env = make("Reverse", n_trailers=n)
    for seed in range(200):
        env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        expected = [-rng.uniform(0.8, 1.2), rng.uniform(-0.05, 0.05)]
        expected += list(rng.uniform(-0.05, 0.05, n))
        np.testing.assert_array_equal(env.unwrapped.core.z[0], expected)


@pytest.mark.parametrize("scene", ["Reverse", "Reverse-v1", "Coast"])
def test_scene_formulas_also_run_without_the_fused_kernel(scene: str) -> None:
    # dopri5 steps outside the compiled step: the Python hooks give reward and termination.
    env_id = f"trailer_env/{scene}" if "-v" in scene else f"trailer_env/{scene}-v0"
    outcomes = []
    for fidelity in ("rk4", "dopri5"):
        env = gym.make(env_id, n_trailers=2, fidelity=fidelity)
        env.reset(seed=1)
        total, steps = 0.0, 0
        for steps in range(1, 301):  # noqa: B007
            _, reward, terminated, truncated, _ = env.step(np.zeros(1, np.float32))
            total += reward
            if terminated or truncated:
                break
        outcomes.append((steps, terminated, total))
    (rk4_steps, rk4_end, rk4_total), (dp_steps, dp_end, dp_total) = outcomes
    assert rk4_end and dp_end and abs(rk4_steps - dp_steps) <= 1
    assert dp_total == pytest.approx(rk4_total, rel=0.05, abs=0.5)
