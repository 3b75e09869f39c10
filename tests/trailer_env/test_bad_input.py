"""Actions, hand-built states and pickling at the environments' untrusted edges."""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest

from tests.trailer_env.helpers import make
from trailer_env.env import real_array
from trailer_env.vector import as_action_batch


def _stepped(env: gym.Env) -> np.ndarray:
    return env.unwrapped.core.z.copy()


@pytest.mark.parametrize(
    "action",
    [
        np.zeros((1, 1), dtype=np.float32),  # (1, 1) is not broadcast to (1,)
        np.zeros(2, dtype=np.float32),
        np.zeros(0, dtype=np.float32),
        [[0.5]],
        [0.1, 0.2],
        np.float32(0.5) * np.ones((1, 1, 1)),
        [[0.1], [0.2, 0.3]],  # ragged
    ],
)
def test_actions_of_the_wrong_shape_are_a_value_error(action: object) -> None:
    env = make("Reverse")
    env.reset(seed=0)
    before = _stepped(env)
    with pytest.raises(ValueError, match="action must"):
        env.step(action)
    np.testing.assert_array_equal(_stepped(env), before)


@pytest.mark.parametrize(
    "action",
    [None, True, np.bool_(False), [True], "0.5", ["0.5"], b"1", 0.5j, [0.5j], [None], {}],
)
def test_actions_that_are_not_real_numbers_are_a_type_error(action: object) -> None:
    env = make("Reverse")
    env.reset(seed=0)
    before = _stepped(env)
    with pytest.raises(TypeError, match="action must"):
        env.step(action)
    np.testing.assert_array_equal(_stepped(env), before)


def test_step_none_says_what_is_wrong() -> None:
    env = make("Coast")
    env.reset(seed=0)
    with pytest.raises(TypeError, match="got NoneType None") as caught:
        env.step(None)
    assert "non-finite" not in str(caught.value)


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_actions_stay_a_value_error(bad: float) -> None:
    env = make("Reverse")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="non-finite"):
        env.step([bad])
    with pytest.raises(ValueError, match="action must be finite"):
        env.step(bad)


def test_planar_mode_needs_both_coordinates() -> None:
    env = make("Reverse", action_mode="planar")
    env.reset(seed=0)
    for action in (0.5, [0.5], np.zeros(1, dtype=np.float32), np.zeros((1, 2))):
        with pytest.raises((TypeError, ValueError), match="action must"):
            env.step(action)
    env.step(np.array([0.5, -0.5], dtype=np.float32))


def test_equivalent_actions_give_identical_steps() -> None:
    """Documented: a 1-D action space takes a plain real number, a list or ints as well."""
    results = []
    for action in (np.array([1.0], dtype=np.float32), [1.0], 1.0, np.float64(1.0), 1, [1]):
        env = make("Reverse")
        env.reset(seed=5)
        obs, reward, *_ = env.step(action)
        results.append((obs, reward))
    for obs, reward in results[1:]:
        np.testing.assert_array_equal(obs, results[0][0])
        assert reward == results[0][1]


class TestVectorActions:
    def test_shapes(self) -> None:
        np.testing.assert_array_equal(as_action_batch([0.1, 0.2, 0.3], 3, 1), [[0.1], [0.2], [0.3]])
        np.testing.assert_array_equal(as_action_batch(np.ones((3, 2)), 3, 2), np.ones((3, 2)))
        assert as_action_batch(np.ones((3, 1), dtype=np.float32), 3, 1).dtype == np.float64
        for bad, dim in (
            (np.ones((1, 1)), 1),  # no broadcasting over the batch
            (np.ones(3), 2),  # (N,) only when d == 1
            (np.ones((3, 1)), 2),
            (np.ones((2, 1)), 1),
            (0.5, 1),
        ):
            with pytest.raises(ValueError, match=r"actions must have shape \(3"):
                as_action_batch(bad, 3, dim)

    @pytest.mark.parametrize(
        "bad", [None, "x", np.ones(3, dtype=bool), np.ones(3) * 1j, [None] * 3]
    )
    def test_types(self, bad: object) -> None:
        with pytest.raises(TypeError, match="actions must be"):
            as_action_batch(bad, 3, 1)

    def test_the_vector_env_refuses_before_stepping(self) -> None:
        envs = gym.make_vec(
            "trailer_env/Reverse-v0", num_envs=3, vectorization_mode="vector_entry_point"
        )
        envs.reset(seed=0)
        before = envs.unwrapped.core.z.copy()
        with pytest.raises(TypeError):
            envs.step(None)
        with pytest.raises(ValueError):
            envs.step(np.zeros((1, 1)))
        np.testing.assert_array_equal(envs.unwrapped.core.z, before)


class TestSetState:
    def test_types(self) -> None:
        env = make("Coast").unwrapped
        env.reset(seed=0)
        for z in (None, "1,0,0,0", [True, False, True, False], ["1", "0", "0", "0"], [1j, 0, 0, 0]):
            with pytest.raises(TypeError, match="z must"):
                env.set_state(z)
        with pytest.raises(TypeError, match="s must be a real number"):
            env.set_state([1.0, 0.0, 0.0, 0.0], s="0.1")
        with pytest.raises(TypeError, match="s_dot must be a real number"):
            env.set_state([1.0, 0.0, 0.0, 0.0], s_dot=True)

    def test_values(self) -> None:
        env = make("Coast").unwrapped
        env.reset(seed=0)
        with pytest.raises(ValueError, match="z must have length"):
            env.set_state([1.0, 0.0, 0.0])
        with pytest.raises(ValueError, match="z must be finite"):
            env.set_state([1.0, np.nan, 0.0, 0.0])
        with pytest.raises(ValueError, match="s must be finite"):
            env.set_state([1.0, 0.0, 0.0, 0.0], s=np.inf)

    def test_an_overflowing_state_leaves_the_env_unchanged(self) -> None:
        env = make("Coast").unwrapped
        env.reset(seed=0)
        obs = env.set_state([1.0, 0.1, 0.0, 0.0])
        before = env.core.z.copy()
        with pytest.raises(
            ValueError, match=r"z is too large: every component must be within \+-1e\+30"
        ):
            env.set_state([1e200, 1e200, 0.0, 0.0])
        with pytest.raises(ValueError, match="z is too large"):
            env.reset(options={"state": [1.0, 2e30, 0.0, 0.0]})
        flat = r"z must be a flat sequence of real numbers .*got dtype <U1"
        with pytest.raises(TypeError, match=flat):
            env.reset(options={"state": ["1", "0", "0", "0"]})
        with pytest.raises(TypeError, match="s must be a real number"):
            env.reset(options={"state": [1.0, 0.0, 0.0, 0.0], "s": "0.1"})
        np.testing.assert_array_equal(env.core.z, before)
        np.testing.assert_array_equal(env.core.obs[0], obs)
        assert np.isfinite(env.step([0.0])[1])

    def test_integer_state_is_read_as_floats(self) -> None:
        env = make("Coast").unwrapped
        env.reset(seed=0)
        np.testing.assert_array_equal(
            env.set_state([1, 0, 0, 0]), env.set_state([1.0, 0.0, 0.0, 0.0])
        )


def test_pickling_after_render_works_and_renders_again() -> None:
    pytest.importorskip("pygame")
    env = make("Dock", render_mode="rgb_array")
    env.reset(seed=2)
    frame = env.render()
    clone = pickle.loads(pickle.dumps(env))
    assert env.unwrapped._renderer is not None  # the original keeps its renderer
    assert clone.unwrapped._renderer is None
    np.testing.assert_array_equal(clone.render(), frame)
    action = np.array([0.3], dtype=np.float32)
    np.testing.assert_array_equal(clone.step(action)[0], env.step(action)[0])
    env.close()
    clone.close()


def test_real_array_is_the_one_number_check() -> None:
    expected = "3 real numbers (x, y, heading)"
    np.testing.assert_array_equal(real_array("target", [1, 2, 3], expected), [1, 2, 3])
    must = r"^target must be 3 real numbers \(x, y, heading\), got "
    with pytest.raises(TypeError, match=must + "NoneType None$"):
        real_array("target", None, expected)
    with pytest.raises(ValueError, match=must + r"\[\[1\], \[1, 2\]\]$"):
        real_array("target", [[1], [1, 2]], expected)
    with pytest.raises(TypeError, match=r"complex numbers\), got dtype complex128$"):
        real_array("target", [1j, 0, 0], expected)
    masked = r"^target is a masked array with masked entries \(1 of 3\)"
    with pytest.raises(ValueError, match=masked):
        real_array("target", np.ma.masked_array([1.0, 2.0, 3.0], mask=[0, 1, 0]), expected)
    # Dock's task check reads it: a refused target changes nothing.
    env = make("Dock").unwrapped
    env.reset(seed=0)
    before = env.core.target.copy()
    with pytest.raises(TypeError, match="target must be 3 real numbers"):
        env.reset(options={"target": ["1", "2", "3"]})
    np.testing.assert_array_equal(env.core.target, before)
