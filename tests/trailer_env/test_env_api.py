"""The single env's reset options, keyboard map, version and the package's command line."""

from __future__ import annotations

import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

import trailer_env
from tests.trailer_env.helpers import make


def test_reset_with_a_given_state_matches_set_state() -> None:
    env = make("Heading", n_trailers=1)
    obs, info = env.reset(
        seed=3, options={"state": [0.5, 0.1, 0.2], "s": 0.1, "target_heading": 0.1}
    )
    other = make("Heading", n_trailers=1)
    other.reset(seed=3)
    np.testing.assert_array_equal(
        obs, other.unwrapped.set_state([0.5, 0.1, 0.2], s=0.1, target_heading=0.1)
    )
    assert info["actuator_work"] == 0.0
    assert env.unwrapped.core.target_heading[0] == 0.1


def test_reset_options_do_not_change_the_generator_stream() -> None:
    env = make("Reverse")
    env.reset(seed=4, options={"state": [-1.0, 0.0, 0.0, 0.0]})
    second, _ = env.reset()
    plain = make("Reverse")
    plain.reset(seed=4)
    np.testing.assert_array_equal(second, plain.reset()[0])


def test_task_option_alone_keeps_the_random_start() -> None:
    env = make("Dock")
    env.reset(seed=8)
    start = env.unwrapped.core.z[0].copy()
    env.reset(seed=8, options={"target": (-6.0, 0.5, 0.1)})
    np.testing.assert_array_equal(env.unwrapped.core.z[0], start)
    np.testing.assert_array_equal(env.unwrapped.core.target[0], [-6.0, 0.5, 0.1])


@pytest.mark.parametrize(
    ("options", "error", "match"),
    [
        ({"start": [0.0]}, ValueError, "unknown reset option"),
        ({"target_heading": 0.1}, ValueError, "unknown reset option"),  # Reverse has no target
        ({"s": 0.1}, ValueError, "need 'state'"),
        ({"state": [1.0, 0.0]}, ValueError, "length"),
        ({"state": [1.0, 0.0, 0.0, 0.0], "s": 0.6}, ValueError, "rail"),
        (["state"], TypeError, "options"),
    ],
)
def test_bad_reset_options(options: object, error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        make("Reverse").reset(seed=0, options=options)  # type: ignore[arg-type]


def test_keys_to_action_for_play() -> None:
    keys = make("Reverse").unwrapped.get_keys_to_action()
    assert {k: v.tolist() for k, v in keys.items()} == {("a",): [1.0], ("d",): [-1.0]}
    planar = make("Reverse", action_mode="planar").unwrapped.get_keys_to_action()
    assert len(planar) == 8
    assert planar[("a", "w")].tolist() == [1.0, 1.0]
    assert planar[("s",)].tolist() == [-1.0, 0.0]
    space = make("Reverse", action_mode="planar").action_space
    assert all(space.contains(action) for action in planar.values())


def test_version_and_command_line_listing() -> None:
    from importlib.metadata import version

    assert trailer_env.__version__ == version("trailer-env")
    listing = subprocess.run(
        [sys.executable, "-m", "trailer_env"], capture_output=True, text=True, check=True
    ).stdout
    ids = [line.split()[0] for line in listing.splitlines() if line.startswith("trailer_env/")]
    assert ids == [spec for spec in gym.registry if spec.startswith("trailer_env/")]
    assert "Reverse-v0" in listing and "400" in listing
    failed = subprocess.run(
        [sys.executable, "-m", "trailer_env", "--play", "trailer_env/Nope-v0"],
        capture_output=True,
        text=True,
    )
    assert failed.returncode == 2 and "Nope-v0" in failed.stderr


def test_a_bad_task_option_leaves_the_state_untouched() -> None:
    env = make("Heading", n_trailers=1)
    env.reset(seed=5)
    core = env.unwrapped.core
    with pytest.raises(ValueError, match="target_heading"):
        env.reset(seed=5, options={"state": [1.0, 0.0, 0.0], "target_heading": float("nan")})
    np.testing.assert_allclose(core.obs[0, :2], core.z[0, :2], rtol=1e-6)  # obs matches z
    assert core.z[0, 0] != 1.0
