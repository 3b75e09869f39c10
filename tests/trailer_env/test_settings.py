"""Settings: defaults, ConvoyParams overrides, and errors that name the bad argument.

A bad type (bools, strings, complex, None, lists) or an unknown keyword is a TypeError,
a bad value a ValueError; OverflowError never escapes.
"""

from __future__ import annotations

import math
import re

import gymnasium as gym
import numpy as np
import pytest

from dynamics import ConvoyParams
from dynamics.params import MAX_TRAILERS
from tests.trailer_env.helpers import make
from trailer_env.fidelity import Fidelity
from trailer_env.settings import DT_RANGE, EnvSettings, settings_from_kwargs


def test_defaults_override_the_actuator_only() -> None:
    settings = settings_from_kwargs()
    assert settings.params == ConvoyParams(n_trailers=2)
    assert settings.dt == 0.05
    assert settings.fidelity == Fidelity(integrator="rk4", substeps="auto", tolerance=1e-4)
    assert settings.action_mode == "servo"
    assert settings.fold_angle == pytest.approx(math.pi / 2)
    assert settings.rail_speed_max == pytest.approx(2.0 * math.sqrt(4.0 * 0.5))
    assert settings.servo_frequency == 5.0


def test_gym_make_passes_params_through() -> None:
    env = make("Reverse", n_trailers=3, mu=0.4, b=0.8, dt=0.02, fidelity={"substeps": 3})
    settings = env.unwrapped.settings
    assert settings.params.n_trailers == 3
    assert settings.params.mu == 0.4 and settings.params.b == 0.8
    assert settings.dt == 0.02 and settings.fidelity.substeps == 3
    assert env.observation_space.shape == (2 * 3 + 4,)
    env.close()


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"n_trailers": -1}, "n_trailers"),
        ({"n_trailers": 1.5}, "n_trailers"),
        ({"mu": -0.1}, "mu"),
        ({"l": 0.0}, "l"),
        ({"M": float("nan")}, "M"),
        ({"M": 10**400}, "M"),
        ({"M": 1e300}, "M"),
        ({"mu": 1e300}, "mu"),
        ({"b": 1e300}, "b"),
        ({"a": 1e300}, "a"),
        ({"l": 1e300}, "l"),
        ({"l": 1e-8}, "l"),
        ({"l": 1e-300}, "l"),
        ({"n_trailers": 10**9}, "n_trailers"),
        ({"n_trailers": 10**400}, "n_trailers"),
        ({"dt": 1e-300}, "dt"),
        ({"dt": 1e300}, "dt"),
        ({"dt": 10**400}, "dt"),
        ({"dt": 0.0}, "dt"),
        ({"dt": float("inf")}, "dt"),
        ({"action_mode": "steer"}, "action_mode"),
        ({"rail_accel_max": -1.0}, "rail_accel_max"),
        ({"rail_accel_max": 1000.0}, "rail_accel_max"),
        ({"servo_bandwidth": 0.0}, "servo_bandwidth"),
        ({"singular_band": 1.0}, "singular_band"),
        ({"fold_angle": 4.0}, "fold_angle"),
        ({"fidelity": "euler"}, "fidelity.integrator"),
        ({"fidelity": {"substeps": 0}}, "fidelity.substeps"),
        ({"fidelity": {"substeps": 10**8}}, "fidelity.substeps"),
        ({"fidelity": 2**63}, "fidelity.substeps"),
        ({"fidelity": {"tolerance": 3.0}}, "fidelity.tolerance"),
        ({"fidelity": {"tolerance": 10**400}}, "fidelity.tolerance"),
        ({"fidelity": {"max_substeps": 10**7}}, "fidelity.max_substeps"),
        ({"fidelity": "rk4-energy"}, "mu = 0"),
        # Combinations that cannot be integrated at the scenes' speeds.
        (
            {
                "l": 5e-6,
                "a": 0.0,
                "b": 0.0,
                "J": 0.0,
                "J0": 1e-5,
                "s_max": 4e-3,
                "rail_accel_max": 1,
            },
            "dt = 0.05 is too long for l = 5e-06",
        ),
        ({"l": 1e-3, "J": 0.0, "fidelity": 1}, "fidelity.substeps = 1 is unstable"),
        ({"l": 1e-6}, r"\|a\| / l"),
        ({"l": 1e-3}, r"J = 0.1 exceeds 100 m l\*\*2"),
    ],
)
def test_invalid_arguments_raise_value_error_naming_them(kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        make("Reverse", **kwargs)
    with pytest.raises(ValueError, match=name):
        gym.make_vec(
            "trailer_env/Reverse-v0", num_envs=2, vectorization_mode="vector_entry_point", **kwargs
        )


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"wheelbase": 2.0}, "wheelbase"),
        ({"frameskip": 4}, "frameskip"),
        ({"fidelity": {"speed": 1}}, "speed"),
        ({"n_trailers": True}, "n_trailers"),
        ({"n_trailers": "2"}, "n_trailers"),
        ({"M": True}, "M"),
        ({"mu": "0.1"}, "mu"),
        ({"l": 1j}, "l"),
        ({"b": None}, "b"),
        ({"a": [0.5]}, "a"),
        ({"dt": "0.05"}, "dt"),
        ({"dt": True}, "dt"),
        ({"rail_accel_max": "4"}, "rail_accel_max"),
        ({"servo_bandwidth": 5j}, "servo_bandwidth"),
        ({"singular_band": None}, "singular_band"),
        ({"fold_angle": False}, "fold_angle"),
        ({"action_mode": 1}, "action_mode"),
        ({"params": {"mu": 0.1}}, "params"),
        ({"fidelity": True}, "fidelity"),
        ({"fidelity": 2.0}, "fidelity"),
        ({"fidelity": [4]}, "fidelity"),
        ({"fidelity": {"substeps": 2.0}}, "fidelity.substeps"),
        ({"fidelity": {"substeps": True}}, "fidelity.substeps"),
        ({"fidelity": {"integrator": 4}}, "fidelity.integrator"),
        ({"fidelity": {"tolerance": "1e-4"}}, "fidelity.tolerance"),
        ({"fidelity": {"max_substeps": 8.0}}, "fidelity.max_substeps"),
    ],
)
def test_wrong_types_and_unknown_keywords_raise_type_error_naming_them(
    kwargs: dict, name: str
) -> None:
    with pytest.raises(TypeError, match=re.escape(name)):
        make("Reverse", **kwargs)
    with pytest.raises(TypeError, match=re.escape(name)):
        gym.make_vec(
            "trailer_env/Reverse-v0", num_envs=2, vectorization_mode="vector_entry_point", **kwargs
        )


def test_range_edges_are_accepted() -> None:
    settings = settings_from_kwargs(
        n_trailers=MAX_TRAILERS, dt=DT_RANGE[0], singular_band=0.0, fold_angle=math.pi
    )
    assert settings.params.n_trailers == MAX_TRAILERS and settings.dt == DT_RANGE[0]
    settings = settings_from_kwargs(dt=DT_RANGE[1], rail_accel_max=1e-6, fidelity=10_000)
    assert settings.dt == 10.0 and settings.fidelity.substeps == 10_000
    assert settings_from_kwargs(n_trailers=np.int64(3), dt=np.float32(0.25)).dt == 0.25


def test_fixed_substeps_must_resolve_the_reference_speed() -> None:
    # dt r / k at |u| = 2 m/s with l = 0.01: 0.05 * 2 / 0.01 / k = 10 / k; the limit is 2.73.
    with pytest.raises(ValueError, match="use at least 4 substeps"):
        settings_from_kwargs(l=0.01, J=0.0, fidelity=3)
    assert settings_from_kwargs(l=0.01, J=0.0, fidelity=4).fidelity.substeps == 4
    assert settings_from_kwargs(l=0.01, J=0.0).fidelity.auto


@pytest.mark.parametrize("render_mode", [1, 1.5, True, b"human", ["human"]])
def test_render_mode_of_the_wrong_type_names_it(render_mode: object) -> None:
    with pytest.raises(TypeError, match="render_mode must be None or one of"):
        make("Reverse", render_mode=render_mode)


@pytest.mark.parametrize("num_envs", [0, -1, 2**40, 1.5])
def test_num_envs_out_of_range_names_it(num_envs: object) -> None:
    with pytest.raises(ValueError, match="num_envs must be an integer in"):
        gym.make_vec(
            "trailer_env/Reverse-v0", num_envs=num_envs, vectorization_mode="vector_entry_point"
        )


@pytest.mark.parametrize("num_envs", [True, "4", None])
def test_num_envs_of_the_wrong_type_names_it(num_envs: object) -> None:
    from trailer_env.scenes import ReverseCore
    from trailer_env.vector import ConvoyVectorEnv

    with pytest.raises(TypeError, match="num_envs must be an integer"):
        ConvoyVectorEnv(ReverseCore, num_envs=num_envs)  # type: ignore[arg-type]


def test_render_mode_is_validated() -> None:
    with pytest.raises(ValueError, match="render_mode"):
        from trailer_env.scenes import ReverseEnv

        ReverseEnv(render_mode="ascii")


def test_params_object_and_n_trailers_must_agree() -> None:
    params = ConvoyParams(n_trailers=1)
    assert settings_from_kwargs(params=params).params is params
    assert settings_from_kwargs(params=params, mu=0.1).params.mu == 0.1
    with pytest.raises(ValueError, match="n_trailers"):
        settings_from_kwargs(params=params, n_trailers=2)


def test_energy_preserving_integrator_is_accepted_without_the_mass() -> None:
    settings = settings_from_kwargs(mu=0.0, fidelity="rk4-energy")
    assert settings.fidelity.integrator == "rk4-energy"
    assert isinstance(settings, EnvSettings)
