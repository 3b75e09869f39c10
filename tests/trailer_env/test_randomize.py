"""Randomised physics and starts (``randomize=``, ``observe_params=``): draws, replay, layout."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest

from trailer_env.randomize import MAX_FACTOR, NAMES, PARAMETERS, PRESETS, Randomization
from trailer_env.scenes.reverse_v1 import PERTURBATION_RADII, SPEED_RANGE
from trailer_env.settings import settings_from_kwargs

REVERSE = "trailer_env/Reverse-v1"
EVERYTHING = {name: (0.7 + 0.05 * k, 1.1 + 0.05 * k) for k, name in enumerate(NAMES)}
NOMINAL = settings_from_kwargs().params


def make_vec(env_id: str, num_envs: int, **kwargs: object) -> gym.vector.VectorEnv:
    return gym.make_vec(
        env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs
    )


def test_draws_are_numpys_after_the_start_and_within_the_ranges() -> None:
    env = gym.make(REVERSE, n_trailers=2, randomize=EVERYTHING)
    for seed in (0, 7, 123):
        _, info = env.reset(seed=seed)
        # Reverse-v1's start (u, then the sphere), then one uniform per name in NAMES order.
        rng = np.random.default_rng(seed)
        u = -rng.uniform(*SPEED_RANGE)
        direction = rng.standard_normal(3)
        factors = [rng.uniform(*EVERYTHING[name]) for name in NAMES]
        params = info["params"]
        for name, factor in zip(PARAMETERS, factors, strict=False):
            assert params[name] == getattr(NOMINAL, name) * factor
            low, high = EVERYTHING[name]
            assert getattr(NOMINAL, name) * low <= params[name] <= getattr(NOMINAL, name) * high
        assert params["speed_factor"] == factors[-1]
        assert env.unwrapped.core.z[0, 0] == u * factors[-1]
        radius = PERTURBATION_RADII[2]
        np.testing.assert_array_equal(
            env.unwrapped.core.z[0, 1:4], radius * direction / np.linalg.norm(direction)
        )
    # The same seed draws the same parameters; another seed others.
    first = env.reset(seed=5)[1]["params"]
    assert env.reset(seed=5)[1]["params"] == first
    assert env.reset(seed=6)[1]["params"]["M"] != first["M"]


def test_without_randomize_every_start_and_stream_is_unchanged() -> None:
    plain = gym.make(REVERSE, n_trailers=3)
    physics = gym.make(REVERSE, n_trailers=3, randomize={"M": (0.8, 1.2), "mu": (0.9, 1.1)})
    off = gym.make(REVERSE, n_trailers=3, randomize=None)
    for env in (plain, physics, off):
        env.reset(seed=31)
    start = plain.unwrapped.core.z.copy()
    # The factors are drawn after the start: the first start is the plain env's.
    np.testing.assert_array_equal(physics.unwrapped.core.z, start)
    np.testing.assert_array_equal(off.unwrapped.core.z, start)
    assert "params" not in plain.reset(seed=31)[1]
    # Later starts come after the factors' draws, so they differ; randomize=None's do not.
    plain.reset()
    physics.reset()
    off.reset()
    np.testing.assert_array_equal(off.unwrapped.core.z, plain.unwrapped.core.z)
    assert not np.array_equal(physics.unwrapped.core.z, plain.unwrapped.core.z)


@pytest.mark.parametrize("env_id", [REVERSE, "trailer_env/Dock-v0", "trailer_env/Coast-v0"])
def test_vector_env_replays_single_envs_bit_for_bit(env_id: str) -> None:
    # 70 environments: two blocks of the block kernels (64 lanes), single envs take the
    # row path: the per-lane parameters give the row's results to the bit.
    ranges = {name: EVERYTHING[name] for name in NAMES if name != "l" or "Dock" not in env_id}
    count, steps, seed = 70, 90, 300
    kwargs = {"n_trailers": 2, "max_episode_steps": 30, "randomize": ranges}
    envs = make_vec(env_id, count, **kwargs)
    singles = [gym.make(env_id, **kwargs) for _ in range(count)]
    vector_obs, infos = envs.reset(seed=seed)
    single = [env.reset(seed=seed + i) for i, env in enumerate(singles)]
    np.testing.assert_array_equal(vector_obs, np.stack([obs for obs, _ in single]))
    for i, (_, info) in enumerate(single):
        assert {key: values[i] for key, values in infos["params"].items()} == info["params"]
    rng = np.random.default_rng(0)
    done = [False] * count
    episodes = 0
    for _ in range(steps):
        actions = rng.uniform(-1, 1, (count, 1)).astype(np.float32)
        vector_obs, rewards, terminated, truncated, infos = envs.step(actions)
        for i, env in enumerate(singles):
            if done[i]:
                obs, info = env.reset()
                reward, term, trunc = 0.0, False, False
                episodes += 1
            else:
                obs, reward, term, trunc, info = env.step(actions[i])
            np.testing.assert_array_equal(vector_obs[i], obs)
            assert rewards[i] == reward and terminated[i] == term and truncated[i] == trunc
            assert infos["params"]["mu"][i] == info["params"]["mu"]
            done[i] = term or trunc
    assert episodes >= count  # every environment drew a second episode's physics


def test_an_episode_simulates_the_drawn_parameters() -> None:
    # The randomised env's episode is, bit for bit, the fixed env made with the drawn values
    # (same start: the factors are drawn after it), auto substeps included.
    ranges = {name: (0.8, 1.2) for name in ("M", "J0", "a", "m", "J", "l", "mu")}
    randomised = gym.make(REVERSE, n_trailers=3, randomize=ranges)
    _, info = randomised.reset(seed=77)
    drawn = {name: info["params"][name] for name in PARAMETERS}
    fixed = gym.make(REVERSE, n_trailers=3, **drawn)
    fixed.reset(seed=77)
    rng = np.random.default_rng(1)
    for _ in range(120):
        action = rng.uniform(-1, 1, 1).astype(np.float32)
        obs, reward, terminated, _, step_info = randomised.step(action)
        expected, expected_reward, expected_terminated, _, expected_info = fixed.step(action)
        np.testing.assert_array_equal(obs, expected)
        assert reward == expected_reward and step_info["energy"] == expected_info["energy"]
        if terminated:
            assert expected_terminated
            break


def test_factors_of_one_give_the_shared_kernels_results_bit_for_bit() -> None:
    # Per-row parameters equal to the nominal ones: the per-lane specialisation of the
    # kernels gives the shared one's results (100 rows: blocks and the row path).
    shared = make_vec(REVERSE, 100, n_trailers=2)
    per_row = make_vec(REVERSE, 100, n_trailers=2, randomize={"M": (1.0, 1.0), "l": (1.0, 1.0)})
    assert per_row.unwrapped.core.step_config.pv.shape == (100, 7)
    assert shared.unwrapped.core.step_config.pv.shape == (7,)
    obs, _ = shared.reset(seed=9)
    # The per-row env drew two more numbers per reset: same first starts only.
    np.testing.assert_array_equal(per_row.reset(seed=9)[0], obs)
    rng = np.random.default_rng(2)
    for _ in range(40):
        actions = rng.uniform(-1, 1, (100, 1))
        result = shared.step(actions)
        other = per_row.step(actions)
        live = ~(result[2] | result[3])
        np.testing.assert_array_equal(result[0][live], other[0][live])
        np.testing.assert_array_equal(result[4]["energy"], other[4]["energy"])
        if not live.all():
            break


def test_observe_params_layout() -> None:
    env = gym.make(REVERSE, n_trailers=2, randomize="mismatch20", observe_params=True)
    obs, info = env.reset(seed=4)
    n = 2
    base = 2 * n + 4  # Reverse adds no task features
    assert obs.shape == (base + 7,)
    expected = [np.log(info["params"][name] / getattr(NOMINAL, name)) for name in PARAMETERS]
    np.testing.assert_array_equal(obs[base:], np.float32(expected))
    assert obs[base + PARAMETERS.index("m")] == 0.0 and obs[base + PARAMETERS.index("J")] == 0.0
    space = env.observation_space
    np.testing.assert_array_equal(space.high[base:], np.float32(np.log(MAX_FACTOR)))
    np.testing.assert_array_equal(space.low[base:], -np.float32(np.log(MAX_FACTOR)))
    # Constant over the episode, recomputed at the next reset.
    stepped = env.step(np.zeros(1, np.float32))[0]
    np.testing.assert_array_equal(stepped[base:], obs[base:])
    assert not np.array_equal(env.reset()[0][base:], obs[base:])
    # Without randomize the features are zeros; Dock's come after its 4 task features.
    plain = gym.make(REVERSE, n_trailers=2, observe_params=True).reset(seed=4)[0]
    np.testing.assert_array_equal(plain[base:], np.zeros(7, np.float32))
    dock = gym.make(
        "trailer_env/Dock-v0", n_trailers=1, randomize={"mu": (0.5, 0.6)}, observe_params=True
    )
    dock_obs, dock_info = dock.reset(seed=1)
    assert dock_obs.shape == (2 * 1 + 4 + 4 + 7,)
    assert dock_obs[10 + PARAMETERS.index("mu")] == np.float32(
        np.log(dock_info["params"]["mu"] / 0.5)
    )


def test_sb3_adapter_reports_the_same_draws() -> None:
    from trailer_env.sb3 import ConvoySB3VecEnv

    adapter = ConvoySB3VecEnv(REVERSE, num_envs=6, n_trailers=2, randomize="mismatch10")
    adapter.seed(50)
    obs = adapter.reset()
    envs = make_vec(REVERSE, 6, n_trailers=2, randomize="mismatch10")
    vector_obs, infos = envs.reset(seed=50)
    np.testing.assert_array_equal(obs, vector_obs)
    for i in range(6):
        assert adapter.reset_infos[i]["params"]["a"] == infos["params"]["a"][i]
    _, _, _, step_infos = adapter.step(np.zeros((6, 1), np.float32))
    assert step_infos[3]["params"]["mu"] == infos["params"]["mu"][3]


def test_presets() -> None:
    preset = Randomization.coerce("mismatch20")
    assert preset is not None
    assert preset.names == ("M", "J0", "a", "l", "mu")
    assert all((low, high) == (0.8, 1.2) for _, low, high in preset.ranges)
    assert set(PRESETS) == {"mismatch10", "mismatch20", "mismatch30", "mismatch40"}
    assert PRESETS["mismatch40"]["mu"] == (0.6, 1.4)
    assert Randomization.coerce({"mu": [0.9, 1.1]}) == Randomization((("mu", 0.9, 1.1),))


@pytest.mark.parametrize(
    ("randomize", "error", "match"),
    [
        ({"M": (1.2, 0.8)}, ValueError, r"randomize\['M'\] = \(1.2, 0.8\): low > high"),
        ({"mu": (0.0, 1.0)}, ValueError, r"randomize\['mu'\] low = 0.0: factors must be in"),
        ({"a": (-1.0, 1.0)}, ValueError, r"randomize\['a'\] low"),
        ({"l": (0.9, float("nan"))}, ValueError, r"randomize\['l'\] high"),
        ({"speed": (0.5, 2e3)}, ValueError, r"randomize\['speed'\] high = 2000.0"),
        ({"b": (0.9, 1.1)}, ValueError, r"unknown name\(s\) \['b'\]"),
        ({"mass": (0.9, 1.1)}, ValueError, r"unknown name\(s\) \['mass'\]"),
        ("mismatch99", ValueError, "unknown preset 'mismatch99'"),
        ({}, ValueError, "empty"),
        ({"M": 1.2}, TypeError, r"randomize\['M'\] must be a \(low, high\) pair"),
        ({"M": (0.8, 1.0, 1.2)}, TypeError, "pair"),
        ({"M": ("0.8", 1.2)}, TypeError, r"randomize\['M'\] low must be a real number"),
        ({"M": (True, 1.2)}, TypeError, "real number"),
        ([("M", 0.8, 1.2)], TypeError, "randomize must be None, a preset name or a dict"),
        ({1: (0.8, 1.2)}, TypeError, "names must be str"),
        # A corner outside ConvoyParams' ranges (M / m <= 1e3), and one that is not
        # integrable: l x 0.001 asks for J <= 100 m l^2 = 1e-4 < J = 0.1.
        ({"m": (0.0005, 1.0)}, ValueError, r"at the corner \(m x 0.0005\).*M / m = 2e\+03"),
        ({"l": (0.001, 1.0)}, ValueError, r"at the corner \(l x 0.001\).*J = 0.1 exceeds"),
    ],
)
def test_bad_ranges_are_refused_by_name(randomize: object, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        settings_from_kwargs(randomize=randomize)
    with pytest.raises(error, match=match):
        gym.make(REVERSE, randomize=randomize)
    with pytest.raises(error, match=match):
        make_vec(REVERSE, 2, randomize=randomize)


def test_bad_combinations_are_refused() -> None:
    with pytest.raises(ValueError, match="needs an RK4 fidelity"):
        settings_from_kwargs(randomize={"M": (0.9, 1.1)}, fidelity="dopri5")
    settings_from_kwargs(randomize={"speed": (0.5, 1.0)}, fidelity="dopri5")  # no physics drawn
    with pytest.raises(ValueError, match=r"DockCore's formulas use \['l'\]"):
        gym.make("trailer_env/Dock-v0", randomize={"l": (0.9, 1.1)})
    # Integrability at a corner: l x 0.05 at dt = 0.1 with one substep is beyond RK4's limit.
    with pytest.raises(ValueError, match=r"at the corner \(l x 0.05\).*substeps = 1 is unstable"):
        settings_from_kwargs(randomize={"l": (0.05, 1.0)}, dt=0.1, fidelity=1)
    settings_from_kwargs(randomize={"l": (0.05, 1.0)}, dt=0.1)  # "auto" resolves it
    with pytest.raises(TypeError, match="observe_params must be a bool"):
        settings_from_kwargs(observe_params=1)
    # A refused reset or make leaves an existing env as it was.
    env = gym.make(REVERSE, randomize="mismatch20")
    obs, info = env.reset(seed=3)
    with pytest.raises(TypeError):
        env.reset(seed=1.5)
    np.testing.assert_array_equal(env.unwrapped.core.obs[0], obs)
    assert env.unwrapped.core.params_info(0) == info["params"]


def test_speed_factor_scales_the_starting_speed_only() -> None:
    plain = gym.make(REVERSE, n_trailers=1)
    fast = gym.make(REVERSE, n_trailers=1, randomize={"speed": (1.5, 1.5)})
    plain.reset(seed=8)
    _, info = fast.reset(seed=8)
    z, z_fast = plain.unwrapped.core.z[0], fast.unwrapped.core.z[0]
    assert info["params"]["speed_factor"] == 1.5 and z_fast[0] == 1.5 * z[0]
    np.testing.assert_array_equal(z_fast[1:], z[1:])
    assert info["params"]["M"] == NOMINAL.M  # the parameters stay nominal
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fast.step(np.zeros(1, np.float32))


# ----------------------------------------------------------- issue 27 item 7
def test_params_are_in_the_infos_with_a_range_of_trailer_counts() -> None:
    # The params of an episode of n are those of the scene made with n_trailers=n whose
    # generator drew the count first (trailer_env.mixed), in the single and vector envs.
    env = gym.make(REVERSE, n_trailers=(1, 3), randomize="mismatch20")
    envs = make_vec(REVERSE, 4, n_trailers=(1, 3), randomize="mismatch20")
    _, batch = envs.reset(seed=10)
    assert batch["_params"].all() and list(batch["params"]) == [*PARAMETERS, "speed_factor"]
    for i in range(4):
        _, info = env.reset(seed=10 + i)
        n = info["n_trailers"]
        rng = np.random.default_rng(10 + i)
        rng.random()  # the count's draw
        single = gym.make(REVERSE, n_trailers=n, randomize="mismatch20")
        single.unwrapped.np_random = rng
        _, expected = single.reset()
        assert info["params"] == expected["params"]
        assert {name: values[i] for name, values in batch["params"].items()} == info["params"]
        _, _, _, _, stepped = env.step(np.zeros(1, dtype=np.float32))
        assert stepped["params"] == expected["params"]
    _, _, _, _, batch = envs.step(np.zeros((4, 1)))
    assert batch["params"]["mu"].shape == (4,)
    plain = gym.make(REVERSE, n_trailers=(1, 3))
    assert "params" not in plain.reset(seed=0)[1]


def test_a_parameter_whose_nominal_is_zero_is_observed_as_it_is() -> None:
    # mu = 0 and J = 0 stay 0 whatever the factor: the factor that holds, and is
    # observed, is 1 (log 0), not the draw (the issue saw -0.44 with mu = 0).
    ranges = {"M": (0.5, 0.6), "J": (0.6, 0.7), "mu": (0.6, 0.7)}
    env = gym.make(REVERSE, n_trailers=1, mu=0.0, J=0.0, randomize=ranges, observe_params=True)
    obs, info = env.reset(seed=0)
    rng = np.random.default_rng(0)
    rng.uniform(*SPEED_RANGE)
    rng.standard_normal(2)
    m_factor = rng.uniform(*ranges["M"])  # J's and mu's are drawn too (same streams)
    assert (info["params"]["mu"], info["params"]["J"]) == (0.0, 0.0)
    assert info["params"]["M"] == NOMINAL.M * m_factor
    np.testing.assert_array_equal(obs[-7:], np.float32([np.log(m_factor), 0, 0, 0, 0, 0, 0]))
    core = env.unwrapped.core
    np.testing.assert_array_equal(core.factors[0, :7], [m_factor, 1, 1, 1, 1, 1, 1])
    core.set_row_params(np.array([0]), np.array([[1.0, 0.2, 0.5, 1.0, 0.05, 1.0, 0.3]]))
    np.testing.assert_array_equal(core.factors[0, :7], [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0])


@pytest.mark.parametrize("preset", ["mismatch10", "mismatch20"])
def test_presets_apply_to_dock_which_keeps_l_nominal(preset: str) -> None:
    low, high = PRESETS[preset]["M"]
    env = gym.make("trailer_env/Dock-v0", n_trailers=1, randomize=preset)
    core = env.unwrapped.core
    assert core.randomization.names == ("M", "J0", "a", "mu")
    assert core.randomization.preset == preset
    for seed in range(5):
        _, info = env.reset(seed=seed)
        params = info["params"]
        assert params["l"] == NOMINAL.l
        for name in ("M", "J0", "a", "mu"):
            factor = params[name] / getattr(NOMINAL, name)
            assert low <= factor <= high
    # Bit for bit the dict of the other four's ranges (the same draws in the same order).
    ranges = {name: PRESETS[preset][name] for name in ("M", "J0", "a", "mu")}
    same = gym.make("trailer_env/Dock-v0", n_trailers=1, randomize=ranges)
    assert same.reset(seed=3)[1]["params"] == env.reset(seed=3)[1]["params"]
    mixed = make_vec("trailer_env/Dock-v0", 3, n_trailers=(1, 2), randomize=preset)
    _, infos = mixed.reset(seed=0)
    np.testing.assert_array_equal(infos["params"]["l"], [NOMINAL.l] * 3)
    # Elsewhere a preset still varies l; a dict naming l is still refused on Dock.
    assert Randomization.coerce(preset).names == ("M", "J0", "a", "l", "mu")  # type: ignore[union-attr]
    with pytest.raises(ValueError, match=r"cannot be randomised in this scene \(a preset"):
        gym.make("trailer_env/Dock-v0", randomize={"l": (0.9, 1.1)})
