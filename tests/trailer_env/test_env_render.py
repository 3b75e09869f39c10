"""The environments' render(): frames from the renderer, unchanged dynamics, RecordVideo."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.trailer_env.helpers import make

pytest.importorskip("pygame")
from trailer_env.rendering import MASS, TARGET


def _has_colour(frame: np.ndarray, colour: tuple[int, int, int]) -> bool:
    return bool(np.any(np.all(frame == np.array(colour, dtype=np.uint8), axis=-1)))


@pytest.mark.parametrize("scene", ["Reverse", "Coast", "Heading", "Dock"])
def test_rgb_array_frames_show_the_convoy(scene: str) -> None:
    env = make(scene, render_mode="rgb_array", n_trailers=2)
    env.reset(seed=0)
    first = env.render()
    assert first.shape == (600, 600, 3) and first.dtype == np.uint8
    assert _has_colour(first, MASS)
    assert _has_colour(first, TARGET) == (scene in ("Heading", "Dock"))
    for _ in range(10):
        env.step(np.array([1.0], dtype=np.float32))
    assert not np.array_equal(env.render(), first)  # the mass moved along its rail
    assert env.metadata["render_fps"] == 20
    env.close()


def test_tracking_the_pose_for_rendering_leaves_the_dynamics_unchanged() -> None:
    plain = make("Reverse")
    drawn = make("Reverse", render_mode="rgb_array")
    plain.reset(seed=3)
    drawn.reset(seed=3)
    for k in range(30):
        action = np.array([np.cos(k / 4)], dtype=np.float32)
        np.testing.assert_array_equal(plain.step(action)[0], drawn.step(action)[0])
    assert len(drawn.unwrapped._path) == 31


def test_human_mode_draws_without_returning_frames() -> None:
    env = make("Coast", render_mode="human", n_trailers=1)
    env.reset(seed=0)
    env.step(np.array([0.5], dtype=np.float32))
    assert env.render() is None
    env.close()


def test_record_video(tmp_path: Path) -> None:
    pytest.importorskip("moviepy")
    from gymnasium.wrappers import RecordVideo

    folder = tmp_path / "videos"
    env = RecordVideo(
        make("Reverse", render_mode="rgb_array"), str(folder), episode_trigger=lambda _: True
    )
    env.reset(seed=0)
    for _ in range(10):
        env.step(np.array([0.0], dtype=np.float32))
    env.close()
    assert list(folder.glob("*.mp4"))
