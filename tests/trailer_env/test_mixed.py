"""Convoys of different lengths in one environment (``n_trailers=(low, high)``)."""

from __future__ import annotations

import copy
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from trailer_env.sb3 import ConvoySB3VecEnv

REVERSE = "trailer_env/Reverse-v1"


def padded_columns(n: int, top: int, tail: int) -> np.ndarray:
    """Where an n-trailer observation's entries sit in the padded layout."""
    return np.concatenate(
        [[0, 1], 2 + np.arange(n), 2 + top + np.arange(n), 2 + 2 * top + np.arange(tail)]
    )


@pytest.mark.parametrize("env_id", [REVERSE, "trailer_env/Dock-v0", "trailer_env/Coast-v0"])
def test_an_episode_of_n_is_the_scene_with_n_trailers_after_one_draw(env_id: str) -> None:
    mixed = gym.make(env_id, n_trailers=(1, 3))
    seen = set()
    for seed in range(12):
        obs, info = mixed.reset(seed=seed)
        n = info["n_trailers"]
        rng = np.random.default_rng(seed)
        assert n == 1 + int(np.floor(rng.random() * 3))  # the documented draw
        seen.add(n)
        single = gym.make(env_id, n_trailers=n)
        single.unwrapped.np_random = rng  # the same stream, after the count's draw
        expected, _ = single.reset()
        tail = expected.size - (2 + 2 * n)
        columns = padded_columns(n, 3, tail)
        np.testing.assert_array_equal(obs[columns], expected)
        padding = np.setdiff1d(np.arange(obs.size - 3), columns)
        assert np.all(obs[padding] == 0.0)
        np.testing.assert_array_equal(obs[-3:], [1.0] * n + [0.0] * (3 - n))  # the mask
        for t in range(30):
            action = np.array([np.sin(0.3 * t + seed)], dtype=np.float32)
            obs, reward, terminated, _, info = mixed.step(action)
            expected, expected_reward, done, _, _ = single.step(action)
            np.testing.assert_array_equal(obs[columns], expected)
            assert reward == expected_reward and terminated == done and info["n_trailers"] == n
            if done:
                break
    assert seen == {1, 2, 3}
    assert mixed.observation_space.shape == (2 + 2 * 3 + tail + 3,)


def replay_rows(
    envs: Any, singles: list, rng: np.random.Generator, steps: int, columns: list
) -> tuple[int, list]:
    """Step ``envs`` with random actions, checking row i (its ``columns[i]``) against
    ``singles[i]`` step for step, autoresets included; the episodes ended and the
    ``info["n_trailers"]`` of every step."""
    needs_reset = np.zeros(len(singles), dtype=bool)
    ended, counts = 0, []
    for _ in range(steps):
        actions = rng.uniform(-1, 1, (len(singles), 1)).astype(np.float32)
        obs, rewards, terminated, truncated, infos = envs.step(actions)
        for i, env in enumerate(singles):
            if needs_reset[i]:  # next_step autoreset: this step reset the env
                expected, _ = env.reset()
                ended += 1
            else:
                expected, reward, done, _, _ = env.step(actions[i])
                assert rewards[i] == reward and terminated[i] == done
            np.testing.assert_array_equal(obs[i, columns[i]], expected)
        counts.append(infos["n_trailers"].tolist())
        needs_reset = terminated | truncated
    return ended, counts


def test_the_vector_env_replays_single_mixed_envs(rng: np.random.Generator) -> None:
    count, seed = 5, 40
    envs = gym.make_vec(
        REVERSE, num_envs=count, vectorization_mode="vector_entry_point", n_trailers=(1, 3)
    )
    singles = [gym.make(REVERSE, n_trailers=(1, 3)) for _ in range(count)]
    obs, infos = envs.reset(seed=seed)
    for i, env in enumerate(singles):
        single_obs, info = env.reset(seed=seed + i)
        np.testing.assert_array_equal(obs[i], single_obs)
        assert infos["n_trailers"][i] == info["n_trailers"]
    everything = [slice(None)] * count
    ended, counts = replay_rows(envs, singles, rng, 160, everything)
    assert ended >= 3 and len(set(counts[-1])) >= 2


def test_the_sb3_adapter_takes_a_range() -> None:
    venv = ConvoySB3VecEnv(REVERSE, num_envs=8, max_episode_steps=20, n_trailers=(1, 2))
    venv.seed(1)
    obs = venv.reset()
    assert obs.shape == (8, 2 + 4 + 2 + 2)
    for _ in range(20):
        obs, _, dones, infos = venv.step(np.zeros((8, 1), dtype=np.float32))
    assert dones.all() and {info["n_trailers"] for info in infos} <= {1, 2}
    assert all(info["episode"]["l"] <= 20 for info in infos)


def test_by_row_each_row_is_the_scene_with_its_count_and_no_draw(
    rng: np.random.Generator,
) -> None:
    """trailer_draw="row": row i runs n = low + i mod count in every episode, exactly the
    env made with that n seeded seed + i (its generator draws no count), autoresets too."""
    count, seed = 7, 100
    envs = gym.make_vec(
        REVERSE,
        num_envs=count,
        vectorization_mode="vector_entry_point",
        n_trailers=(1, 3),
        trailer_draw="row",
    )
    obs, infos = envs.reset(seed=seed)
    np.testing.assert_array_equal(infos["n_trailers"], [1, 2, 3, 1, 2, 3, 1])
    singles = [gym.make(REVERSE, n_trailers=1 + i % 3) for i in range(count)]
    columns = []
    for i, env in enumerate(singles):
        expected, _ = env.reset(seed=seed + i)
        n = 1 + i % 3
        columns.append(padded_columns(n, 3, expected.size - (2 + 2 * n)))
        np.testing.assert_array_equal(obs[i, columns[i]], expected)
    ended, counts = replay_rows(envs, singles, rng, 120, columns)
    assert ended >= 3 and all(step == [1, 2, 3, 1, 2, 3, 1] for step in counts)
    single = gym.make(REVERSE, n_trailers=(2, 3), trailer_draw="row")
    assert all(single.reset(seed=s)[1]["n_trailers"] == 2 for s in range(4))  # row 0


@pytest.mark.parametrize(
    ("value", "error"), [("steps", ValueError), ("", ValueError), (1, TypeError), (None, TypeError)]
)
def test_a_bad_trailer_draw_is_refused_naming_the_choices(value: object, error: type) -> None:
    for counts in ((1, 3), 2):
        with pytest.raises(error, match=r"trailer_draw must be one of \('episode', 'row'\)"):
            gym.make(REVERSE, n_trailers=counts, trailer_draw=value)


def test_one_count_has_nothing_to_draw() -> None:
    plain, _ = gym.make(REVERSE, n_trailers=2).reset(seed=3)
    by_row, _ = gym.make(REVERSE, n_trailers=2, trailer_draw="row").reset(seed=3)
    np.testing.assert_array_equal(plain, by_row)


@pytest.mark.parametrize(
    ("value", "error", "match"),
    [
        ((3, 1), ValueError, "low < high"),
        ((1,), TypeError, "pair"),
        ((0, 20), ValueError, "more than 8"),
        ((1.5, 3), ValueError, r"n_trailers\[0\]"),
        (("1", 3), TypeError, r"n_trailers\[0\]"),
        ((-1, 2), ValueError, r"n_trailers\[0\]"),
    ],
)
def test_bad_ranges_are_refused(value: tuple, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        gym.make(REVERSE, n_trailers=value)


def test_what_needs_one_count_is_refused_with_a_range() -> None:
    with pytest.raises(ValueError, match="rendering"):
        gym.make(REVERSE, n_trailers=(1, 2), render_mode="rgb_array")
    env = gym.make(REVERSE, n_trailers=(1, 2))
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"a state of n in 1\.\.2 trailers"):
        env.reset(options={"state": [-1.0, 0.0, 0.0, 0.0, 0.0]})  # 2 + 3: no count's
    with pytest.raises(ValueError, match="reset option"):
        env.reset(options={"target_heading": 0.0})
    with pytest.raises(ValueError, match="non-finite"):
        env.step(np.array([np.nan], dtype=np.float32))
    assert env.step(np.zeros(1, dtype=np.float32))[0].shape == (2 + 4 + 2 + 2,)


# ------------------------------------------------- issue 27: a refused step changes nothing
def _core_arrays(core: Any) -> dict[str, np.ndarray]:
    """Every per-row array of a core (the kernels' scratch and the step's inputs aside):
    what a refused step must leave as it was."""
    arrays = {
        name: value.copy()
        for name, value in vars(core).items()
        if isinstance(value, np.ndarray)
        and value.shape[:1] == (core.batch_size,)
        and not name.startswith("_")
        and name != "act"
    }
    if hasattr(core, "act"):  # columns 4, 5: the step's commanded acceleration
        arrays["act"] = core.act[:, :4].copy()
    return arrays


def _mixed_arrays(mixed: Any) -> dict[str, np.ndarray]:
    arrays = {f"mixed.{name}": value for name, value in _core_arrays(mixed).items()}
    for key, value in mixed.info_batch().items():
        columns = value if isinstance(value, dict) else {"": value}  # params: a dict of arrays
        arrays.update({f"mixed.info.{key}.{name}": column for name, column in columns.items()})
    for n, core in mixed.cores.items():
        live = mixed.trailers == n  # a core's other rows hold nothing anyone reads
        arrays.update({f"{n}.{name}": value[live] for name, value in _core_arrays(core).items()})
    return arrays


def _assert_same(before: dict[str, np.ndarray], after: dict[str, np.ndarray]) -> None:
    assert before.keys() == after.keys()
    for name, value in before.items():
        np.testing.assert_array_equal(after[name], value, err_msg=name)


def test_a_refused_step_moves_no_count_the_issue_s_case() -> None:
    # Issue 27 item 3: n = 3 rows diverge at t = 3 after the n = 1 rows had stepped
    # (row 1 moved by 1.7e5 in its observation), and the failed rows kept a NaN reward.
    envs = gym.make_vec(
        REVERSE,
        num_envs=8,
        vectorization_mode="vector_entry_point",
        n_trailers=(1, 3),
        randomize={"speed": (1, 1000)},
        fidelity=1,
    )
    mixed = envs.unwrapped.core
    envs.reset(seed=4)
    rng = np.random.default_rng(0)
    for _ in range(3):
        envs.step(rng.uniform(-1.0, 1.0, (8, 1)))
    assert mixed.trailers.tolist() == [1, 1, 3, 1, 2, 3, 3, 3]
    before = _mixed_arrays(mixed)
    with pytest.raises(FloatingPointError, match=r"environment\(s\) \[2, 5\].*previous step"):
        envs.step(rng.uniform(-1.0, 1.0, (8, 1)))
    _assert_same(before, _mixed_arrays(mixed))
    assert np.isfinite(mixed.cores[3].reward[[2, 5]]).all()


def test_a_refused_step_takes_back_the_counts_stepped_before_it() -> None:
    # Heading keeps a hold counter and a potential per row (Python hooks): a row of n = 3
    # made to diverge is stepped after the n = 1 and n = 2 rows, which are taken back.
    envs = gym.make_vec(
        "trailer_env/Heading-v0",
        num_envs=8,
        vectorization_mode="vector_entry_point",
        n_trailers=(1, 3),
        fidelity=1,
    )
    mixed = envs.unwrapped.core
    envs.reset(seed=2)
    actions = np.full((8, 1), 0.4)
    for _ in range(5):
        envs.step(actions)
    assert sorted(set(mixed.trailers.tolist())) == [1, 2, 3]
    row = int(np.flatnonzero(mixed.trailers == 3)[0])
    twin = copy.deepcopy(envs)  # steps the same rows, without the divergence
    mixed.cores[3].z[row, 0] = 20000.0
    mixed.cores[3].refresh(np.array([row]))
    mixed.cores[3].energy0[row] = twin.unwrapped.core.cores[3].energy0[row]
    before = _mixed_arrays(mixed)
    with pytest.raises(FloatingPointError, match=rf"environment\(s\) \[{row}\]"):
        envs.step(actions)
    _assert_same(before, _mixed_arrays(mixed))
    # Put the row back as the twin has it: from there both replay each other bit for bit.
    mixed.cores[3].z[row] = twin.unwrapped.core.cores[3].z[row]
    mixed.cores[3].refresh(np.array([row]))
    for _ in range(3):
        obs, reward, terminated, _, _ = envs.step(actions)
        twin_obs, twin_reward, twin_terminated, _, _ = twin.step(actions)
        np.testing.assert_array_equal(obs, twin_obs)
        np.testing.assert_array_equal(reward, twin_reward)
        np.testing.assert_array_equal(terminated, twin_terminated)
    _assert_same(_mixed_arrays(twin.unwrapped.core), _mixed_arrays(mixed))


def test_a_refused_step_of_one_count_keeps_the_last_results() -> None:
    env = gym.make("trailer_env/Reverse-v0", fidelity=1)
    env.reset(seed=0, options={"state": [-1.0, 0.0, 0.1, -0.1]})
    env.step(np.full(1, 0.5, dtype=np.float32))
    core = env.unwrapped.core
    core.z[0, 0] = -20000.0
    core.refresh()
    results = [core.reward.copy(), core.terminated.copy(), core.success.copy()]
    with pytest.raises(FloatingPointError, match=r"environment\(s\) \[0\]"):
        env.step(np.zeros(1, dtype=np.float32))  # its reward was NaN, its flags the step's
    for array, result in zip((core.reward, core.terminated, core.success), results, strict=True):
        np.testing.assert_array_equal(array, result)
    assert np.isfinite(core.reward[0]) and core.success[0]
