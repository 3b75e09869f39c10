"""The wheel, installed in a fresh venv outside the clone: envs, a shipped model's
evaluation with a video, the main job and the console scripts (slow: about 2 minutes)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

SNIPPET = """
import gymnasium as gym, numpy as np, trailer_env
from trailer_env.benchmark import score
env = gym.make("trailer_env/Dock-v0", n_trailers=1)
obs, _ = env.reset(seed=0)
assert env.observation_space.contains(obs)
print("score", score(lambda o: np.zeros((len(o), 1)), "trailer_env/Reverse-v1", 1, episodes=5)
      .summary["episodes"])
"""


def run(command: list[str], cwd: Path, timeout: int = 600) -> str:
    environment = {**os.environ, "SDL_VIDEODRIVER": "dummy", "MPLBACKEND": "Agg"}
    environment.pop("PYTHONPATH", None)
    result = subprocess.run(
        command, cwd=cwd, env=environment, capture_output=True, text=True, timeout=timeout
    )
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-3000:]
    return result.stdout


def wheel_venv(tmp_path: Path, extras: str, *, torch: bool) -> tuple[Path, Path, Path]:
    """The project's wheel installed with ``extras`` in a fresh venv: (venv, its python,
    an empty working folder outside the clone)."""
    run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path), "."], ROOT)
    (wheel,) = tmp_path.glob("trailer_env-*.whl")
    venv = tmp_path / "venv"
    run([sys.executable, "-m", "venv", str(venv)], tmp_path)
    python = venv / "bin" / "python"
    constraints = str(ROOT / "constraints.txt")
    if torch:  # the CPU build first: an unpinned torch would fetch the CUDA wheels
        run(
            [str(python), "-m", "pip", "install", "-q", "-c", constraints, "torch==2.13.0"],
            tmp_path,
        )
    run(
        [str(python), "-m", "pip", "install", "-q", "-c", constraints, f"{wheel}[{extras}]"],
        tmp_path,
    )
    work = tmp_path / "elsewhere"
    work.mkdir()
    return venv, python, work


@pytest.mark.slow
def test_the_wheel_works_outside_the_clone(tmp_path: Path) -> None:
    venv, python, work = wheel_venv(tmp_path, "agents,rendering", torch=True)
    located = run([str(python), "-c", "import agents, trailer_env; print(agents.__file__)"], work)
    assert str(ROOT) not in located and "site-packages" in located
    assert "score 5" in run([str(python), "-c", SNIPPET], work)
    run(
        [
            str(venv / "bin" / "trailer-env-evaluate"),
            "--policy",
            "dagger_reverse_v1_n2",
            "--episodes",
            "3",
            "--no-plots",
            "--out",
            "eval",
            "--video",
            "x.mp4",
            "--video-steps",
            "30",
        ],
        work,
    )
    assert (work / "x.mp4").stat().st_size > 1000
    assert json.loads((work / "eval" / "results.json").read_text())["episodes"] == 3
    printed = run([str(python), "-m", "agents.main", "--out", "main", "--episodes", "10"], work)
    assert "| mpc-replay |" in printed and "| dagger_reverse_v1_n2 |" in printed
    assert "trailer_env/Reverse-v1" in run([str(venv / "bin" / "trailer-env")], work)
    assert sorted(path.name for path in work.iterdir()) == ["eval", "main", "x.mp4"]


RECORD_VIDEO = """
import gymnasium as gym, numpy as np, trailer_env
from gymnasium.wrappers import RecordVideo
env = RecordVideo(gym.make("trailer_env/Reverse-v1", render_mode="rgb_array"), "videos")
env.reset(seed=0)
for _ in range(20):
    env.step(np.zeros(1, dtype=np.float32))
env.close()
"""


@pytest.mark.slow
def test_record_video_needs_only_the_rendering_extra(tmp_path: Path) -> None:
    _, python, work = wheel_venv(tmp_path, "rendering", torch=False)
    run([str(python), "-c", RECORD_VIDEO], work)
    (video,) = (work / "videos").glob("*.mp4")
    assert video.stat().st_size > 1000
