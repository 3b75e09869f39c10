"""Write one GIF per environment and policy: the committed agent and the zero action.

Every GIF is one episode from the same test seed (:data:`SEED`), rendered with
``gym.make(id, render_mode="rgb_array", n_trailers=n)``, every second control step kept
(10 frames per second of simulated time at the default ``dt = 0.05``, so it plays in real
time), at most :data:`MAX_SECONDS` seconds, downscaled to :data:`SIZE` pixels and written
with Pillow. The committed agent is loaded by :func:`agents.policies.load_policy`.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
from PIL import Image

import trailer_env  # noqa: F401  (registers the ids)

#: The test seed of every GIF (the first of the results tables' test seeds 1000-1099).
SEED = 1000
#: Frames per second of the GIF; with ``dt = 0.05`` one frame every second step.
FPS = 10
#: Longest episode shown, in seconds of simulated time.
MAX_SECONDS = 12.0
#: Side of the square GIF, in pixels.
SIZE = 320
#: Where the GIFs go (``docs/img``).
#: Default folder: nothing tracked is rewritten unless ``--out docs/img`` asks for it.
OUT = Path("out/gifs")
#: The GIFs' index beside them (policy, seed, length and outcome of each; the site's
#: captions read it).
INDEX = "gifs.json"


@dataclass(frozen=True)
class Clip:
    """One environment's GIFs: its id, the number of trailers and its committed agent."""

    env_id: str
    n_trailers: int
    agent: str

    @property
    def stem(self) -> str:
        """``reverse_v1`` for ``trailer_env/Reverse-v1``."""
        return self.env_id.split("/")[1].replace("-", "_").lower()

    def file_name(self, policy: str) -> str:
        """``gif_reverse_v1_n2_zero.gif``, ``gif_reverse_v1_n2_agent.gif``."""
        return f"gif_{self.stem}_n{self.n_trailers}_{policy}.gif"


#: Every registered environment, with the committed agent the results tables headline.
CLIPS = (
    Clip("trailer_env/Reverse-v0", 2, "ppo_reverse_n2"),
    Clip("trailer_env/Reverse-v1", 2, "dagger_reverse_v1_n2"),
    Clip("trailer_env/Coast-v0", 1, "ppo_coast_n1"),
    Clip("trailer_env/Heading-v0", 2, "sac_heading_n2"),
    Clip("trailer_env/Dock-v0", 1, "ppo_dock_n1"),
)

Policy = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Episode:
    """What one recorded episode shows, for the caption."""

    frames: list[Image.Image]
    steps: int
    seconds: float
    outcome: str


def record(clip: Clip, policy: Policy, *, seed: int = SEED, size: int = SIZE) -> Episode:
    """Run one seeded episode under ``policy`` and keep every ``1 / (FPS dt)``-th frame."""
    env = gym.make(clip.env_id, render_mode="rgb_array", n_trailers=clip.n_trailers)
    try:
        dt = float(env.unwrapped.settings.dt)  # type: ignore[attr-defined]
        every = max(1, round(1.0 / (FPS * dt)))
        max_steps = round(MAX_SECONDS / dt)
        obs, _ = env.reset(seed=seed)
        frames = [_frame(env.render(), size)]
        steps, outcome = 0, "running"
        while steps < max_steps:
            action = np.asarray(policy(np.asarray(obs)[None]))[0]
            obs, _, terminated, truncated, info = env.step(action)
            steps += 1
            if steps % every == 0 or terminated or truncated:
                frames.append(_frame(env.render(), size))
            if terminated or truncated:
                outcome = _outcome(info, terminated)
                break
        return Episode(frames, steps, steps * dt, outcome)
    finally:
        env.close()


def _frame(rgb: object, size: int) -> Image.Image:
    image = Image.fromarray(np.asarray(rgb, dtype=np.uint8))
    return image.resize((size, size), Image.Resampling.LANCZOS)


def _outcome(info: dict, terminated: bool) -> str:
    if info.get("is_success"):
        return "success"
    return "failure" if terminated else "time limit"


def write_gif(episode: Episode, path: Path) -> None:
    """Write the frames as a looping GIF (the last frame held for one second)."""
    # One palette for the whole GIF, from a strip of frames across the episode (the
    # convoy's colour follows its singular margin, so early and late frames differ).
    picks = episode.frames[:: max(1, len(episode.frames) // 8)] + episode.frames[-1:]
    width, height = picks[0].size
    strip = Image.new("RGB", (width * len(picks), height))
    for i, frame in enumerate(picks):
        strip.paste(frame, (i * width, 0))
    palette = strip.quantize(colors=64, method=Image.Quantize.MEDIANCUT)
    frames = [f.quantize(palette=palette, dither=Image.Dither.NONE) for f in episode.frames]
    durations = [1000 // FPS] * len(frames)
    durations[-1] = 1000
    path.parent.mkdir(parents=True, exist_ok=True)
    frames[0].save(
        path,
        save_all=True,
        append_images=frames[1:],
        duration=durations,
        loop=0,
        optimize=True,
        disposal=1,
    )


def policies_for(clip: Clip) -> dict[str, Policy]:
    """The two policies of a clip's GIFs: ``agent`` (committed model) and ``zero``."""
    from agents.policies import load_policy

    kwargs = {"n_trailers": clip.n_trailers}
    return {
        "agent": load_policy(clip.agent, clip.env_id, kwargs),
        "zero": load_policy("zero", clip.env_id, kwargs),
    }


def main(argv: Sequence[str] | None = None) -> None:
    """The command line."""
    parser = argparse.ArgumentParser(prog="python -m docs.gifs", description=__doc__)
    parser.add_argument(
        "--out", type=Path, default=OUT, help="folder (default out/gifs; docs/img: the site's)"
    )
    parser.add_argument("--only", nargs="*", default=None, help="environment ids to draw")
    args = parser.parse_args(argv)
    index_path = args.out / INDEX
    index = json.loads(index_path.read_text()) if index_path.is_file() else {}
    for clip in CLIPS:
        if args.only and clip.env_id not in args.only:
            continue
        for name, policy in policies_for(clip).items():
            start = time.perf_counter()
            episode = record(clip, policy)
            path = args.out / clip.file_name(name)
            write_gif(episode, path)
            print(
                f"{path}: {len(episode.frames)} frames, {episode.seconds:.1f} s, "
                f"{episode.outcome}, {path.stat().st_size / 1024:.0f} kB "
                f"({time.perf_counter() - start:.1f} s)",
                flush=True,
            )
            index[path.name] = {
                "env_id": clip.env_id,
                "n_trailers": clip.n_trailers,
                "policy": clip.agent if name == "agent" else "zero",
                "seed": SEED,
                "frames": len(episode.frames),
                "seconds": round(episode.seconds, 2),
                "outcome": episode.outcome,
            }
    index_path.write_text(json.dumps(index, indent=2, sort_keys=True) + "\n")
