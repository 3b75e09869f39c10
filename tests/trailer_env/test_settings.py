"""Settings: defaults, ConvoyParams overrides, and ValueErrors that name the bad argument."""

from __future__ import annotations

import math

import gymnasium as gym
import pytest

from dynamics import ConvoyParams
from tests.trailer_env.helpers import make
from trailer_env.fidelity import Fidelity
from trailer_env.settings import EnvSettings, settings_from_kwargs


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
        ({"wheelbase": 2.0}, "wheelbase"),
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
        ({"fidelity": {"tolerance": 3.0}}, "fidelity.tolerance"),
        ({"fidelity": {"speed": 1}}, "fidelity"),
        ({"fidelity": "rk4-energy"}, "mu = 0"),
    ],
)
def test_invalid_arguments_raise_value_error_naming_them(kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        make("Reverse", **kwargs)
    with pytest.raises(ValueError, match=name):
        gym.make_vec(
            "trailer_env/Reverse-v0", num_envs=2, vectorization_mode="vector_entry_point", **kwargs
        )


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
