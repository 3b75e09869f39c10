"""Other libraries' conventions: safety-gymnasium's step and goal-conditioned Dict envs."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest

import trailer_env  # noqa: F401  (registers the ids)
from trailer_env.wrappers import GoalConditioned, SafetyStep


def test_the_safety_step_returns_the_cost_third() -> None:
    plain = gym.make("trailer_env/Reverse-v1", n_trailers=2)
    safe = SafetyStep(gym.make("trailer_env/Reverse-v1", n_trailers=2))
    plain.reset(seed=3)
    safe.reset(seed=3)
    costs = []
    for step in range(200):
        action = np.array([np.sin(0.1 * step)], dtype=np.float32)
        obs, reward, terminated, truncated, info = plain.step(action)
        result = safe.step(action)
        assert len(result) == 6
        np.testing.assert_array_equal(result[0], obs)
        assert result[1] == reward and result[2] == info["cost"] == result[5]["cost"]
        assert result[3:5] == (terminated, truncated)
        costs.append(result[2])
        if terminated or truncated:
            break
    assert set(costs) <= {0.0, 1.0}


@pytest.mark.parametrize(
    ("env_id", "goal"), [("trailer_env/Dock-v0", 4), ("trailer_env/Heading-v0", 2)]
)
def test_goal_conditioned_observations_and_reward(env_id: str, goal: int) -> None:
    env = GoalConditioned(gym.make(env_id, n_trailers=2))
    obs, _ = env.reset(seed=1000)
    assert env.observation_space.contains(obs)
    assert obs["observation"].shape == (8,) and obs["achieved_goal"].shape == (goal,)
    achieved, desired = obs["achieved_goal"], obs["desired_goal"]
    assert env.compute_reward(achieved, achieved, {}) == 0.0
    assert env.compute_reward(achieved, desired, {}) == -1.0  # no start is already there
    pairs = np.stack([achieved, desired]), np.stack([desired, desired])
    batch = env.compute_reward(*pairs, [{}] * 2)
    np.testing.assert_array_equal(batch, [-1.0, 0.0])
    obs, reward, _, _, info = env.step(np.zeros(1, dtype=np.float32))
    assert reward == env.compute_reward(obs["achieved_goal"], obs["desired_goal"], info)
    assert "scene_reward" in info


def test_the_dock_goal_is_reached_exactly_where_the_scene_says_docked() -> None:
    env = GoalConditioned(gym.make("trailer_env/Dock-v0", n_trailers=1))
    obs, _ = env.reset(seed=0)
    x, y, sin_h, cos_h = (float(v) for v in obs["achieved_goal"])
    heading = float(np.arctan2(sin_h, cos_h))
    for offset, docked in ((0.29, True), (0.31, False)):
        desired = np.array([x + offset, y, sin_h, cos_h])
        assert bool(env.compute_reward(obs["achieved_goal"], desired, {}) == 0.0) is docked
    turned = np.array([x, y, np.sin(heading + 0.16), np.cos(heading + 0.16)])
    assert env.compute_reward(obs["achieved_goal"], turned, {}) == -1.0
    with pytest.raises(ValueError, match="needs trailer_env/Dock-v0 or trailer_env/Heading-v0"):
        GoalConditioned(gym.make("trailer_env/Reverse-v1"))


def test_sb3_her_trains_on_the_goal_view() -> None:
    sb3 = pytest.importorskip("stable_baselines3")
    model = sb3.SAC(
        "MultiInputPolicy",
        GoalConditioned(gym.make("trailer_env/Heading-v0", n_trailers=1)),
        replay_buffer_class=sb3.HerReplayBuffer,
        replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
        learning_starts=301,  # HER samples whole episodes: after the first (300 steps)
        batch_size=32,
        seed=0,
    )
    model.learn(320)
    assert model.num_timesteps == 320 and model.replay_buffer.size() == 320


@pytest.mark.slow
def test_her_learns_to_hold_a_heading_on_a_short_budget() -> None:
    """SAC + HER, 6000 steps (about 2 minutes on a core): 0 of 30 held by the zero action,
    25 of 30 after training when measured (seeds 5000..5029)."""
    sb3 = pytest.importorskip("stable_baselines3")
    import torch

    torch.set_num_threads(1)

    def make() -> GoalConditioned:
        return GoalConditioned(gym.make("trailer_env/Heading-v0", n_trailers=1))

    def successes(model: object) -> int:
        env, count = make(), 0
        for k in range(30):
            obs, _ = env.reset(seed=5000 + k)
            done = False
            while not done:
                action = model.predict(obs, deterministic=True)[0] if model else np.zeros(1)  # type: ignore[attr-defined]
                obs, _, terminated, truncated, info = env.step(action)
                done = terminated or truncated
            count += bool(info["is_success"])
        return count

    model = sb3.SAC(
        "MultiInputPolicy",
        make(),
        replay_buffer_class=sb3.HerReplayBuffer,
        replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
        learning_starts=300,
        seed=0,
    )
    assert successes(None) == 0
    model.learn(6000)
    assert successes(model) >= 20


# ----------------------------------------------------------- issue 27 item 6
def test_gymnasium_s_checker_passes_and_the_spec_rebuilds_the_wrappers() -> None:
    from gymnasium.utils.env_checker import check_env

    for env_id in ("trailer_env/Dock-v0", "trailer_env/Heading-v0"):
        env = GoalConditioned(gym.make(env_id, n_trailers=1))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # Box bounds of +-inf: by design
            check_env(env, skip_render_check=True)
    env = GoalConditioned(gym.make("trailer_env/Dock-v0", n_trailers=1))
    assert env.spec is not None
    assert [wrapper.entry_point for wrapper in env.spec.additional_wrappers[-1:]] == [
        "trailer_env.wrappers:GoalConditioned"
    ]
    again = env.spec.make()
    assert isinstance(again, GoalConditioned) and again.unwrapped.core.n == 1
    first, _ = env.reset(seed=5)
    second, _ = again.reset(seed=5)
    for key, value in first.items():
        np.testing.assert_array_equal(second[key], value)
    safe = SafetyStep(gym.make("trailer_env/Reverse-v1", n_trailers=3))
    assert safe.spec is not None
    rebuilt = safe.spec.make()
    assert isinstance(rebuilt, SafetyStep) and rebuilt.unwrapped.core.n == 3
    rebuilt.reset(seed=0)
    assert len(rebuilt.step(np.zeros(1, dtype=np.float32))) == 6


@pytest.mark.parametrize("wrapper", [GoalConditioned, SafetyStep])
def test_the_wrappers_refuse_what_they_cannot_wrap(wrapper: type) -> None:
    name = wrapper.__name__
    made = "needs an environment made with gym.make"
    cases: list[tuple[object, type[Exception], str]] = [
        (None, TypeError, f"{name} {made}\\('trailer_env/...'\\), got NoneType None"),
        ("trailer_env/Dock-v0", TypeError, f"{made}.*got str 'trailer_env/Dock-v0'"),
        (
            gym.make("CartPole-v1"),
            ValueError,
            f"{name} needs a trailer_env environment, got CartPole-v1",
        ),
        (
            gym.make_vec(
                "trailer_env/Dock-v0", num_envs=2, vectorization_mode="vector_entry_point"
            ),
            TypeError,
            f"{name} wraps one environment, got the vector env DockVectorEnv",
        ),
    ]
    for env, error, message in cases:
        with pytest.raises(error, match=message):
            wrapper(env)
    if wrapper is GoalConditioned:
        for env_id, core in (
            ("trailer_env/Reverse-v1", "ReverseV1Core"),
            ("trailer_env/Dock-v0", "MixedCore"),
        ):
            kwargs = {"n_trailers": (1, 2)} if core == "MixedCore" else {}
            with pytest.raises(ValueError, match=f"Dock-v0 or .*Heading-v0 .*got a {core}"):
                GoalConditioned(gym.make(env_id, **kwargs))


def test_compute_reward_checks_the_goals() -> None:
    env = GoalConditioned(gym.make("trailer_env/Dock-v0", n_trailers=1))
    obs, _ = env.reset(seed=0)
    goal = obs["achieved_goal"].astype(np.float64)
    width = r"goals of shape \(\.\.\., 4\)"
    cases: list[tuple[object, object, type[Exception], str]] = [
        # The case: 5 entries each, the 5th ignored, and the goals "agreed".
        (
            np.r_[goal, 9.0],
            np.r_[goal, -9.0],
            ValueError,
            rf"achieved_goal must be {width}, got shape \(5,\)",
        ),
        (goal[:3], goal[:3], ValueError, r"got shape \(3,\)"),
        (None, goal, TypeError, rf"achieved_goal must be {width}, got NoneType None"),
        (goal, 1.0, ValueError, rf"desired_goal must be {width}, got shape \(\)"),
        (goal, "abcd", TypeError, "desired_goal must be .* got str 'abcd'"),
        (goal, [[1.0, 2.0], [3.0]], ValueError, "desired_goal must be .* got a ragged"),
        (goal.astype(object), goal, TypeError, "of real numbers, got dtype object"),
        (
            np.zeros((5, 4)),
            np.zeros((3, 4)),
            ValueError,
            r"achieved_goal \(5, 4\) and desired_goal \(3, 4\): the leading \(batch\) axes",
        ),
    ]
    for achieved, desired, error, message in cases:
        with pytest.raises(error, match=message):
            env.compute_reward(achieved, desired, None)
    # Batched leading axes, as hindsight relabelling passes them, and broadcasting.
    batch = np.stack([goal, goal + np.array([1.0, 0.0, 0.0, 0.0])])
    np.testing.assert_array_equal(env.compute_reward(batch, goal, None), [0.0, -1.0])
    np.testing.assert_array_equal(
        env.compute_reward(batch[np.newaxis], batch[:, np.newaxis], None),
        [[0.0, -1.0], [-1.0, 0.0]],
    )
    assert env.compute_reward(goal.astype(np.float32).tolist(), goal, None) == 0.0
    heading = GoalConditioned(gym.make("trailer_env/Heading-v0", n_trailers=1))
    with pytest.raises(ValueError, match=r"goals of shape \(\.\.\., 2\), got shape \(4,\)"):
        heading.compute_reward(goal, goal, None)
