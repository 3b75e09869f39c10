"""Pictures of an evaluation: learning curves, singular-margin histograms, rendered frames.

Every function writes one PNG (matplotlib, Agg backend) and returns its path.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from agents.artifacts import files
from agents.artifacts.curves import STEPS_COLUMN, read_curve
from agents.envs import MakeKwargs, make_keywords
from agents.evaluation.metrics import EpisodeResults
from agents.policies.baselines import Policy
from trailer_env.benchmark import privileged_view

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: Axis labels of the curve metrics.
METRIC_LABELS = {
    "safe_rate": "safe episodes (never in band, no fold, no stop)",
    "success_rate": "successful episodes",
    "jackknife_rate": "folded episodes",
}


def _pyplot() -> ModuleType:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _draw_curves(
    axis: Axes,
    curves: Mapping[str, Path],
    metric: str,
    baselines: Mapping[str, float] | None,
) -> None:
    """One line per run of ``metric`` against steps (log axis), baselines as dashed lines."""
    for label, path in curves.items():
        rows = [row for row in read_curve(Path(path)) if row[STEPS_COLUMN] > 0]
        if rows:
            steps = [row[STEPS_COLUMN] for row in rows]
            axis.plot(steps, [row[metric] for row in rows], marker=".", ms=3, label=label)
    for index, (label, value) in enumerate((baselines or {}).items()):
        axis.axhline(value, color=f"C{7 + index % 3}", ls="--", lw=1, label=label)
    axis.set_xscale("log")
    axis.set_xlabel("environment steps")
    axis.grid(alpha=0.3)


def plot_learning_curves(
    curves: Mapping[str, Path],
    out: Path,
    baselines: Mapping[str, float] | None = None,
    title: str = "",
    metric: str = "safe_rate",
) -> Path:
    """Validation ``metric`` (default: safe rate) and mean return against training steps.

    Args:
        curves: Label -> evaluations.csv written by
            :class:`agents.training.callbacks.SafetyEvalCallback`.
        out: PNG path.
        baselines: Label -> the baseline's value of ``metric``, drawn as dashed lines.
        title: Figure title.
        metric: A column of evaluations.csv.
    """
    plt = _pyplot()
    fig, (ax_metric, ax_return) = plt.subplots(1, 2, figsize=(11, 4))
    _draw_curves(ax_metric, curves, metric, baselines)
    _draw_curves(ax_return, curves, "mean_return", None)
    ax_metric.set_ylim(-0.02, 1.02)
    ax_metric.set_ylabel(METRIC_LABELS.get(metric, metric))
    ax_return.set_ylabel("mean return")
    ax_metric.legend(fontsize=8)
    return _save(fig, plt, out, title)


#: Panels per row of :func:`plot_curve_grid`.
CURVE_GRID_COLUMNS = 4


def plot_curve_grid(
    panels: Sequence[tuple[str, Mapping[str, Path], Mapping[str, float], str]], out: Path
) -> Path:
    """Several scenes' learning curves, four to a row: (title, curves, baselines, metric) each."""
    plt = _pyplot()
    columns = min(CURVE_GRID_COLUMNS, max(len(panels), 1))
    rows = -(-len(panels) // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(4.2 * columns, 3.8 * rows), squeeze=False)
    for axis in axes.flat[len(panels) :]:
        axis.set_visible(False)
    for axis, (title, curves, baselines, metric) in zip(axes.flat, panels, strict=False):
        _draw_curves(axis, curves, metric, baselines)
        axis.set_ylim(-0.02, 1.02)
        axis.set_title(title, fontsize=10)
        axis.set_ylabel(METRIC_LABELS.get(metric, metric), fontsize=9)
        axis.legend(fontsize=7, loc="best")
    return _save(fig, plt, out)


def plot_margin_histograms(
    results: Mapping[str, EpisodeResults], singular_band: float, out: Path, title: str = ""
) -> Path:
    """Distribution of the singular margin over all steps (left) and of each episode's minimum.

    The singular band ``margin < singular_band`` is shaded.
    """
    plt = _pyplot()
    fig, (ax_steps, ax_min) = plt.subplots(1, 2, figsize=(11, 4))
    bins = np.linspace(0.0, 1.0, 41)
    for label, result in results.items():
        ax_steps.hist(result.margins, bins=bins, histtype="step", lw=1.5, density=True, label=label)
        ax_min.hist(result.min_margin, bins=bins, histtype="step", lw=1.5, label=label)
    for axis in (ax_steps, ax_min):
        axis.axvspan(0.0, singular_band, color="red", alpha=0.08, label="singular band")
        axis.set_xlim(0.0, 1.0)
        axis.grid(alpha=0.3)
    ax_steps.set_yscale("log")
    ax_steps.set_xlabel("singular margin (every step)")
    ax_steps.set_ylabel("density")
    ax_min.set_xlabel("smallest singular margin of the episode")
    ax_min.set_ylabel("episodes")
    ax_min.legend(fontsize=8)
    return _save(fig, plt, out, title)


def render_frames(
    env_id: str,
    policy: Policy,
    seed: int,
    env_kwargs: MakeKwargs | None = None,
    times: Sequence[float] = (0.0, 2.0, 4.0, 8.0, 14.0, 20.0),
) -> tuple[list[np.ndarray], list[str]]:
    """Render one seeded episode of ``policy`` at the given times (s); stops at the episode's end.

    Returns the RGB frames and their captions (the time, the singular margin and how
    the episode ended: the picture's text, since the frame's own is too small to read
    once the frames are reduced to fit a page).
    """
    import gymnasium as gym

    env = gym.make(env_id, render_mode="rgb_array", **make_keywords(env_kwargs))
    dt = env.unwrapped.settings.dt  # type: ignore[attr-defined]
    wanted = sorted({round(t / dt) for t in times})
    obs, info = env.reset(seed=seed)
    frames: list[np.ndarray] = []
    captions: list[str] = []
    step, ended = 0, False
    while True:
        if step in wanted or ended:
            frames.append(np.asarray(env.render()))
            tag = ", folded" if ended and info.get("jackknifed") else (", end" if ended else "")
            margin = float(info.get("singular_margin", 1.0))
            captions.append(f"t = {step * dt:.1f} s{tag}\nmargin {margin:.2f}")
        if ended or step >= max(wanted):
            break
        obs, _, terminated, truncated, info = env.step(policy(_seen(policy, env, obs))[0])
        step += 1
        ended = bool(terminated or truncated)
    env.close()
    return frames, captions


def _seen(policy: Policy, env: Any, obs: np.ndarray) -> Any:
    """What ``policy`` reads for the single env's observation ``obs`` (a batch of one):
    the observation, or a privileged policy's view of the env's core
    (:func:`trailer_env.benchmark.privileged_view`)."""
    observe = privileged_view(policy)
    batch = obs[None]
    return batch if observe is None else observe(env.unwrapped.core, batch)


#: Rows of a rendered frame left out when cropping (as fractions of its height): the
#: frame's own text at the top and its scale bar at the bottom, unreadable once reduced.
FRAME_TEXT_TOP, FRAME_TEXT_BOTTOM = 0.08, 0.9


def frame_crop(frames: Sequence[np.ndarray], pad: int = 12) -> tuple[slice, slice]:
    """(rows, columns) of the frames' common box around everything drawn (the convoy and
    its path, not the background), padded by ``pad`` pixels; one box for all frames, so
    that every frame keeps the same scale and place.

    Raises:
        ValueError: If ``frames`` is empty or the frames differ in shape.
    """
    if not frames or len({frame.shape for frame in frames}) != 1:
        raise ValueError("frames must be one or more images of one shape")
    height, width = frames[0].shape[:2]
    top, bottom = int(FRAME_TEXT_TOP * height), int(FRAME_TEXT_BOTTOM * height)
    drawn = np.zeros((height, width), dtype=bool)
    for frame in frames:
        drawn |= np.any(np.abs(frame.astype(np.int16) - frame[top, -1]) > 12, axis=2)
    drawn[:top] = drawn[bottom:] = False
    rows, columns = np.flatnonzero(drawn.any(axis=1)), np.flatnonzero(drawn.any(axis=0))
    if rows.size == 0:
        return slice(top, bottom), slice(0, width)
    return (
        slice(max(rows[0] - pad, top), min(rows[-1] + pad + 1, bottom)),
        slice(max(columns[0] - pad, 0), min(columns[-1] + pad + 1, width)),
    )


#: The widest picture the site shows at 100 %: its content column at a 1280 px window
#: (938 px on the results page, less a margin). A wider one is scaled down to fit, and its
#: text with it (the frames picture was 1500 px: its 10 pt captions showed at 6 pt).
PAGE_WIDTH_PX = 930
#: Resolution of the site's pictures: 1 pt of text is 100 / 72 px, so 10 pt is 14 px.
PAGE_DPI = 100
#: The smallest text of :func:`plot_frames`, in points at :data:`PAGE_DPI`.
FRAME_FONT_PT = 10


def plot_frames(
    rows: Mapping[str, tuple[list[np.ndarray], list[str]]], out: Path, title: str = ""
) -> Path:
    """A grid of rendered frames: one row per policy (label -> frames, captions), each
    frame cropped to the box of :func:`frame_crop` over all of them.

    The picture is :data:`PAGE_WIDTH_PX` wide at :data:`PAGE_DPI`, so that the site shows
    it at 100 % and no text is smaller than :data:`FRAME_FONT_PT` (14 px) on the page: the
    policy's name stands above its row rather than beside it, leaving the width to the
    frames. A newline in ``title`` breaks it.

    Raises:
        ValueError: If ``rows`` is empty.
    """
    if not rows:
        raise ValueError("no rows of frames to draw")
    plt = _pyplot()
    columns = max(len(frames) for frames, _ in rows.values())
    box_rows, box_columns = frame_crop([frame for frames, _ in rows.values() for frame in frames])
    aspect = (box_rows.stop - box_rows.start) / (box_columns.stop - box_columns.start)
    width = PAGE_WIDTH_PX / PAGE_DPI
    # A frame's height plus two caption lines and the row's name (inches).
    row_height = 0.93 * width / columns * aspect + 0.8
    title_height = 0.3 * (title.count("\n") + 1) if title else 0.0
    fig = plt.figure(figsize=(width, row_height * len(rows) + title_height), layout="constrained")
    for subfigure, (label, (frames, captions)) in zip(
        fig.subfigures(len(rows), 1, squeeze=False)[:, 0], rows.items(), strict=True
    ):
        subfigure.suptitle(label, x=0.01, ha="left", fontsize=FRAME_FONT_PT + 1, fontweight="bold")
        for column, axis in enumerate(subfigure.subplots(1, columns, squeeze=False)[0]):
            axis.set_xticks([])
            axis.set_yticks([])
            axis.set_anchor("N")  # under its name; spare height goes below the captions
            if column < len(frames):
                axis.imshow(frames[column][box_rows, box_columns])
                axis.set_xlabel(captions[column], fontsize=FRAME_FONT_PT, labelpad=2)
            else:
                axis.axis("off")
    if title:
        fig.suptitle(title, fontsize=FRAME_FONT_PT + 2)
    out.parent.mkdir(parents=True, exist_ok=True)
    with files.replacing(out) as temporary:
        fig.savefig(temporary, dpi=PAGE_DPI)
    plt.close(fig)
    return out


def save_page_figure(fig: Figure, plt: ModuleType, out: Path) -> Path:
    """Write a page-width figure laid out by its own constraints to ``out`` atomically, at
    :data:`PAGE_DPI`, and close it."""
    with files.replacing(out) as temporary:
        fig.savefig(temporary, dpi=PAGE_DPI)
    plt.close(fig)
    return out


def _save(fig: Figure, plt: ModuleType, out: Path, title: str = "") -> Path:
    """Lay out ``fig`` (under ``title``, if any), write it to ``out`` and close it."""
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    with files.replacing(out) as temporary:
        fig.savefig(temporary, dpi=80)
    plt.close(fig)
    return out


def episode_frames(
    env_id: str,
    policy: Policy,
    seed: int,
    env_kwargs: MakeKwargs | None = None,
    max_steps: int | None = None,
) -> list[np.ndarray]:
    """Every ``rgb_array`` frame of one seeded episode of ``policy`` (single env).

    The first frame is the reset state, then one per step: an episode of L steps gives
    L + 1 frames (fewer when ``max_steps`` < L cuts it: ``max_steps`` + 1).
    """
    import gymnasium as gym

    env = gym.make(env_id, render_mode="rgb_array", **make_keywords(env_kwargs))
    obs, _ = env.reset(seed=seed)
    frames = [np.asarray(env.render())]
    steps = 0
    while max_steps is None or steps < max_steps:
        obs, _, terminated, truncated, _ = env.step(policy(_seen(policy, env, obs))[0])
        frames.append(np.asarray(env.render()))
        steps += 1
        if terminated or truncated:
            break
    env.close()
    return frames


#: Video formats :func:`write_video` writes.
VIDEO_SUFFIXES = (".mp4", ".gif")
#: The modules a video of each suffix needs beyond the frames' (pygame, ``rendering``).
VIDEO_MODULES = {".mp4": ("pygame", "imageio", "imageio_ffmpeg"), ".gif": ("pygame", "PIL")}


def missing_video_modules(out: Path) -> list[str]:
    """The modules a video written to ``out`` needs that are not installed."""
    import importlib.util

    needed = VIDEO_MODULES.get(out.suffix.lower(), ())
    return [name for name in needed if importlib.util.find_spec(name) is None]


def write_video(frames: Sequence[np.ndarray], out: Path, fps: float) -> Path:
    """Write ``frames`` as an mp4 (imageio's ffmpeg, the ``rendering`` extra) or a gif (Pillow).

    Raises:
        ValueError: For another suffix than .mp4 or .gif, or no frames.
    """
    if out.suffix.lower() not in VIDEO_SUFFIXES:
        raise ValueError(f"video must end in {' or '.join(VIDEO_SUFFIXES)}, got {out.name!r}")
    if not frames:
        raise ValueError("no frames to write")
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix.lower() == ".gif":
        from PIL import Image

        images = [Image.fromarray(frame) for frame in frames]
        # optimize=False and disposal=1 keep one GIF frame per env frame (Pillow would
        # otherwise merge frames that happen to be identical).
        with files.replacing(out) as temporary:
            images[0].save(
                temporary,
                format="GIF",
                save_all=True,
                append_images=images[1:],
                duration=round(1000 / fps),
                loop=0,
                optimize=False,
                disposal=1,
            )
        return out
    import imageio.v2 as imageio

    # macro_block_size=1: the frames' size need not be a multiple of 16.
    with files.replacing(out) as temporary:
        imageio.mimsave(temporary, list(frames), fps=fps, macro_block_size=1)
    return out
