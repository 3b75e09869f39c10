"""Learning curves over training seeds: grouping run folders, bands, plateaus, the chart.

A run folder (``agents.train``) holds ``config.json`` (its scene, n, algorithm and seed)
and ``evaluations.csv`` (the validation evaluations: steps, wall time and the rates).
:func:`read_run` reads one; :func:`group_runs` puts runs of the same (environment,
n, algorithm) together, one per training seed; :func:`seed_band` gives a group's mean
and min-max band of the scene's headline rate (safe for Reverse, success otherwise)
against environment steps or wall time; :func:`plateau` finds where a curve first went
flat (what an early stop acts on) and :func:`final_plateau` where it settled for good
(what the table reports);
:func:`write_learning_curves` draws the chart (PNG) and writes the table (Markdown),
both atomically and only over earlier files with ``overwrite``.

The plateau rule: a curve is flat at evaluation ``i`` when its last ``window``
evaluations (``i - window + 1 .. i``) all lie within ``eps`` of their mean. The first
such ``i`` is where the plateau is *detected* (what an early stop can act on: see
``--stop-on-plateau`` of ``agents.train``); the plateau *starts* at the window's first
evaluation. A rate measured on 50 validation episodes moves by 0.02 per episode, and
its binomial standard error near 0.7 is 0.065: ``eps`` well under that calls noise a
trend, and the default of the command (``5,0.05``) treats five evaluations within 0.05
of their mean as flat.

That rule is sized for curves near 1.0, where the noise is small: a curve flat at 0.8
passes it in only about a fifth of its windows (five evaluations of 50 episodes, sd
0.057 each). Whether a curve still climbs is asked of its end instead by
:func:`trend`: the least-squares line through the evaluations of its last third of
steps (at least :data:`TREND_MIN_EVALUATIONS`), the rise that line makes over them and
its standard error; it is *rising* when the rise exceeds its error times Student's t
(one-sided 97.5 %, on the fit's degrees of freedom: 3.18 for five evaluations, 2.1-2.2
for ten to twenty), so that five points that happen to line up are not called a climb.
"""

from __future__ import annotations

import io
import math
import textwrap
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agents.algorithms.recipes import recipe_name
from agents.artifacts import files
from agents.artifacts.cards import ModelCard
from agents.artifacts.curves import read_curve
from agents.artifacts.run_folder import CONFIG_FILE, CURVE_FILE
from agents.envs import headline_metric, scene_title

__all__ = [
    "CHART_FILE",
    "TABLE_FILE",
    "TREND_FRACTION",
    "TREND_MIN_EVALUATIONS",
    "Band",
    "Plateau",
    "RunCurve",
    "Trend",
    "bands_overlap",
    "final_plateau",
    "group_runs",
    "is_rising",
    "plateau",
    "read_run",
    "rise_text",
    "seed_band",
    "student_t",
    "trend",
    "write_learning_curves",
]

#: What :func:`write_learning_curves` writes in its folder.
CHART_FILE = "learning_curves.png"
TABLE_FILE = "learning_curves.md"
#: The x axes of a band: evaluations.csv's step count and its wall time.
AXES = ("timesteps", "wall_s")

#: The end of a curve that :func:`trend` fits: its last third of steps, and at least
#: five evaluations (fewer leave the line's error on two or three degrees of freedom).
TREND_FRACTION = 1 / 3
TREND_MIN_EVALUATIONS = 5

#: A run's trailers: one count, or a generalist's range ``(low, high)``.
TrailerCounts = int | tuple[int, int]
#: (environment id, number of trailers, algorithm): one group of runs over training seeds.
GroupKey = tuple[str, TrailerCounts, str]


@dataclass(frozen=True)
class RunCurve:
    """One run folder's learning curve.

    Attributes:
        run_dir: The folder.
        env_id, n_trailers, algo, seed: From its ``config.json`` (``n_trailers`` a pair for
            a generalist's range); ``algo`` names its reward state-dependent exploration and
            reward shaping too ("ppo (gSDE) + lqr shaping").
        rows: Its ``evaluations.csv`` rows (floats), in step order.
    """

    run_dir: Path
    env_id: str
    n_trailers: TrailerCounts
    algo: str
    seed: int
    rows: tuple[dict[str, float], ...]

    @property
    def metric(self) -> str:
        """The scene's headline rate (a column of the rows)."""
        return headline_metric(self.env_id)

    def series(self, axis: str = "timesteps") -> tuple[np.ndarray, np.ndarray]:
        """(x, headline rate) of every evaluation; ``axis`` is "timesteps" or "wall_s"."""
        x = np.array([row[axis] for row in self.rows])
        return x, np.array([row[self.metric] for row in self.rows])


@dataclass(frozen=True)
class Plateau:
    """Where a curve went flat (see the module's docstring).

    Attributes:
        step: The x (step) of the evaluation at which the plateau is detected.
        start: The x of the window's first evaluation.
        level: The window's mean.
    """

    step: float
    start: float
    level: float


@dataclass(frozen=True)
class Trend:
    """The least-squares line through a curve's last evaluations (:func:`trend`).

    Attributes:
        start, end: The x of the first and last evaluation fitted.
        change: The line's rise from ``start`` to ``end`` (slope times ``end - start``).
        se: Its standard error (from the residuals; 0 for points on a line).
        evaluations: How many were fitted.
    """

    start: float
    end: float
    change: float
    se: float
    evaluations: int

    @property
    def rising(self) -> bool:
        """Whether the curve still climbs (:func:`is_rising`)."""
        return is_rising(self.change, self.se, self.evaluations)

    def text(self) -> str:
        """:func:`rise_text` of the trend."""
        return rise_text(self.change, self.se, self.evaluations)


#: Student's t, one-sided 97.5 % (two-sided 95 %), by degrees of freedom 1..30.
_STUDENT_T = (12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228,
              2.201, 2.179, 2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086,
              2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042)  # fmt: skip
_NORMAL_975 = 1.959964


def student_t(dof: int) -> float:
    """Student's t at one-sided 97.5 % for ``dof`` >= 1 degrees of freedom (the table to
    30, then the normal quantile with two Cornish-Fisher terms, within 0.0002)."""
    if dof < 1:
        raise ValueError(f"dof must be >= 1, got {dof}")
    if dof <= len(_STUDENT_T):
        return _STUDENT_T[dof - 1]
    z = _NORMAL_975
    return z + (z**3 + z) / (4 * dof) + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * dof**2)


def is_rising(change: float, se: float, evaluations: int) -> bool:
    """Whether a fitted rise over ``evaluations`` points exceeds its standard error times
    :func:`student_t` of the fit's ``evaluations - 2`` degrees of freedom."""
    return change > student_t(evaluations - 2) * se


def rise_text(change: float, se: float, evaluations: int) -> str:
    """A trend in the tables: "+0.02 ± 0.03", and ", rising" when :func:`is_rising`."""
    rising = ", rising" if is_rising(change, se, evaluations) else ""
    return f"{change:+.2f} ± {se:.2f}{rising}"


@dataclass(frozen=True)
class Band:
    """A group's curves on one x grid: the mean and the min-max over the seeds.

    Attributes:
        x: The grid: every seed's evaluation x within the range all seeds cover.
        mean, low, high: Over the seeds, each seed linearly interpolated onto ``x``.
        seeds: How many curves.
    """

    x: np.ndarray
    mean: np.ndarray
    low: np.ndarray
    high: np.ndarray
    seeds: int


def _check_window(window: object, eps: object) -> tuple[int, float]:
    if isinstance(window, bool) or not isinstance(window, (int, np.integer)):
        raise TypeError(f"window must be an integer, got {type(window).__name__}")
    if window < 2:
        raise ValueError(f"window must be >= 2 evaluations, got {window}")
    if isinstance(eps, bool) or not isinstance(eps, (int, float, np.floating, np.integer)):
        raise TypeError(f"eps must be a number, got {type(eps).__name__}")
    if not (math.isfinite(eps) and eps >= 0):
        raise ValueError(f"eps must be a finite number >= 0, got {eps!r}")
    return int(window), float(eps)


def is_flat(values: Sequence[float] | np.ndarray, window: int, eps: float) -> bool:
    """Whether the last ``window`` of ``values`` all lie within ``eps`` of their mean
    (False while there are fewer; a window of non-finite values is not flat)."""
    if len(values) < window:
        return False
    last = np.asarray(values[-window:], dtype=float)
    if not np.all(np.isfinite(last)):
        return False
    # The tolerance absorbs the rounding of the mean (0.7 + 0.7 + ... is not exact).
    return bool(np.max(np.abs(last - last.mean())) <= eps + 1e-12)


def _curve(
    steps: Sequence[float] | np.ndarray, values: Sequence[float] | np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``steps`` and ``values`` as float arrays, checked as :func:`plateau` documents."""
    x = np.asarray(steps, dtype=float)
    y = np.asarray(values, dtype=float)
    if x.ndim != 1 or x.shape != y.shape:
        raise ValueError(f"steps and values must be 1-D of one length, got {x.shape}, {y.shape}")
    if not np.all(np.isfinite(x)) or np.any(np.diff(x) <= 0):
        raise ValueError("steps must be finite and strictly increasing")
    return x, y


def plateau(
    steps: Sequence[float] | np.ndarray,
    values: Sequence[float] | np.ndarray,
    window: int,
    eps: float,
) -> Plateau | None:
    """The first evaluation at which ``values`` is flat (the module's rule), or None.

    Args:
        steps: The evaluations' steps (or any increasing x), as long as ``values``.
        values: The rate at each.
        window: Evaluations in the window (>= 2).
        eps: The band around the window's mean (>= 0).

    Raises:
        TypeError: If ``window`` is not an integer or ``eps`` not a number.
        ValueError: On a window < 2, a negative or non-finite ``eps``, lengths that
            differ, or steps that are not finite and strictly increasing.
    """
    window, eps = _check_window(window, eps)
    x, y = _curve(steps, values)
    for i in range(window - 1, len(y)):
        if is_flat(y[: i + 1], window, eps):
            level = float(y[i - window + 1 : i + 1].mean())
            return Plateau(step=float(x[i]), start=float(x[i - window + 1]), level=level)
    return None


def final_plateau(
    steps: Sequence[float] | np.ndarray,
    values: Sequence[float] | np.ndarray,
    window: int,
    eps: float,
) -> Plateau | None:
    """Where a curve settled for good, or None when its end is not flat.

    The curve's end is flat when its last ``window`` evaluations lie within ``eps`` of
    their mean (the level); it settled at the first evaluation from which every later
    one stays within ``eps`` of that level. Unlike :func:`plateau`, a flat stretch
    before a jump (a run at 0 for its first million steps) is not the plateau.
    ``step`` and ``start`` are both that first evaluation's x.

    Raises:
        As :func:`plateau`.
    """
    window, eps = _check_window(window, eps)
    x, y = _curve(steps, values)
    if not is_flat(y, window, eps):
        return None
    level = float(y[-window:].mean())
    outside = np.flatnonzero(np.abs(y - level) > eps + 1e-12)
    first = 0 if outside.size == 0 else int(outside[-1]) + 1
    return Plateau(step=float(x[first]), start=float(x[first]), level=level)


def trend(
    steps: Sequence[float] | np.ndarray,
    values: Sequence[float] | np.ndarray,
    fraction: float = TREND_FRACTION,
    minimum: int = TREND_MIN_EVALUATIONS,
) -> Trend | None:
    """The least-squares line through a curve's end: the evaluations in its last
    ``fraction`` of steps (from ``last - fraction (last - first)``), or its last
    ``minimum`` when that holds fewer; None when the curve has fewer than ``minimum``.

    A fixed count of evaluations would reach back into the rise of a run evaluated
    seldom (ten evaluations of a 2M-step run every 0.2M are all of it), and call a curve
    that rose and then sat flat "rising".

    Raises:
        TypeError: If ``minimum`` is not an integer or ``fraction`` not a number.
        ValueError: On ``minimum`` < 3 (a line through two points has no error),
            ``fraction`` outside (0, 1], or steps and values as :func:`plateau` refuses.
    """
    if isinstance(minimum, bool) or not isinstance(minimum, (int, np.integer)):
        raise TypeError(f"minimum must be an integer, got {type(minimum).__name__}")
    if minimum < 3:
        raise ValueError(f"minimum must be >= 3 evaluations, got {minimum}")
    if isinstance(fraction, bool) or not isinstance(fraction, (int, float, np.floating)):
        raise TypeError(f"fraction must be a number, got {type(fraction).__name__}")
    if not 0.0 < fraction <= 1.0:
        raise ValueError(f"fraction must be in (0, 1], got {fraction!r}")
    x, y = _curve(steps, values)
    if len(y) < minimum:
        return None
    count = max(int(np.count_nonzero(x >= x[-1] - fraction * (x[-1] - x[0]))), minimum)
    x, y = x[-count:], y[-count:]
    centred = x - x.mean()
    spread = float(np.dot(centred, centred))
    slope = float(np.dot(centred, y - y.mean())) / spread
    residuals = y - y.mean() - slope * centred
    variance = float(np.dot(residuals, residuals)) / (count - 2)
    span = float(x[-1] - x[0])
    return Trend(
        start=float(x[0]),
        end=float(x[-1]),
        change=slope * span,
        se=math.sqrt(variance / spread) * span,
        evaluations=count,
    )


def read_run(run_dir: Path) -> RunCurve:
    """A run folder's configuration and learning curve.

    Raises:
        ValueError: If the folder has no ``config.json`` or ``evaluations.csv``, either
            is unreadable, the configuration lacks the environment, n, algorithm or
            seed, or the curve has no row or lacks the scene's headline rate.
    """
    config_path, curve_path = run_dir / CONFIG_FILE, run_dir / CURVE_FILE
    for path in (config_path, curve_path):
        if not path.is_file():
            raise ValueError(f"{run_dir} is not a run folder: it has no {path.name}")
    config = ModelCard.from_json(
        files.read_json(config_path, "run configuration"), str(config_path)
    )
    env_id, n_trailers, seed = config.env_id, config.n_trailers, config.seed
    missing = [
        name
        for name, value in (("env_id", env_id), ("algo", config.algo), ("n_trailers", n_trailers))
        if value is None
    ]
    if env_id is None or missing:
        raise ValueError(f"{config_path} lacks the run's environment, n, algorithm: {missing}")
    algo = recipe_name(config.to_json())  # gSDE and shaping are recipes of their own
    metric = headline_metric(env_id)
    counts: TrailerCounts
    if isinstance(n_trailers, tuple) or (isinstance(n_trailers, int) and n_trailers >= 1):
        counts = n_trailers
    else:
        raise ValueError(f"{config_path}: n_trailers must be an integer or a range [low, high]")
    if seed is None or seed < 0:
        raise ValueError(f"{config_path}: seed must be an integer")
    rows = read_curve(curve_path, ("wall_s", metric))
    if not rows:
        raise ValueError(f"{curve_path} has no evaluation")
    rows.sort(key=lambda row: row["timesteps"])
    return RunCurve(run_dir, env_id, counts, algo, int(seed), tuple(rows))


def counts_text(counts: TrailerCounts) -> str:
    """``2`` or ``1-3``."""
    return f"{counts[0]}-{counts[1]}" if isinstance(counts, tuple) else str(counts)


def group_runs(runs: Sequence[RunCurve]) -> dict[GroupKey, list[RunCurve]]:
    """Runs by (environment, n, algorithm), each group's runs by seed.

    Raises:
        ValueError: If a group holds two runs of the same seed (two folders of one run).
    """
    groups: dict[GroupKey, list[RunCurve]] = {}
    for run in runs:
        groups.setdefault((run.env_id, run.n_trailers, run.algo), []).append(run)
    for key, members in groups.items():
        members.sort(key=lambda run: run.seed)
        seeds = [run.seed for run in members]
        if len(set(seeds)) != len(seeds):
            raise ValueError(
                f"{key[0]} n = {counts_text(key[1])} {key[2]}: two runs of one seed "
                f"({', '.join(str(run.run_dir) for run in members)})"
            )
    return groups


def seed_band(runs: Sequence[RunCurve], axis: str = "timesteps") -> Band:
    """Mean and min-max of the runs' headline rate against ``axis`` ("timesteps", "wall_s").

    Raises:
        ValueError: On no runs, an unknown axis, or runs whose x ranges do not overlap.
    """
    if axis not in AXES:
        raise ValueError(f"axis must be one of {AXES}, got {axis!r}")
    if not runs:
        raise ValueError("no runs to draw")
    series = [run.series(axis) for run in runs]
    start, end = _common_range(series)
    if start > end:
        raise ValueError(f"the runs' {axis} ranges do not overlap ({start:g} > {end:g})")
    grid = np.unique(np.concatenate([x[(x >= start) & (x <= end)] for x, _ in series]))
    if grid.size == 0:
        grid = np.array([start])
    values = np.array([np.interp(grid, x, y) for x, y in series])
    return Band(grid, values.mean(axis=0), values.min(axis=0), values.max(axis=0), len(runs))


def _common_range(series: Sequence[tuple[np.ndarray, np.ndarray]]) -> tuple[float, float]:
    """The x range every curve covers (start > end when they do not overlap)."""
    return max(float(x[0]) for x, _ in series), min(float(x[-1]) for x, _ in series)


def bands_overlap(runs: Sequence[RunCurve], axis: str) -> bool:
    """Whether the runs cover a common ``axis`` range, so :func:`seed_band` can draw them.

    Wall time may not: a run whose first evaluation waited for a kernel compile can start
    after a short run ended.
    """
    start, end = _common_range([run.series(axis) for run in runs])
    return start <= end


def _group_label(key: GroupKey) -> str:
    env_id, n, algo = key
    return f"{scene_title(env_id)}, n = {counts_text(n)}, {algo}"


def _rate_text(values: Sequence[float]) -> str:
    array = np.asarray(values, dtype=float)
    spread = f" ({array.min():.2f}-{array.max():.2f})" if array.size > 1 else ""
    return f"{array.mean():.2f} ± {array.std():.2f}{spread}"


def markdown_table(
    groups: Mapping[GroupKey, Sequence[RunCurve]],
    window: int,
    eps: float,
    levels: Mapping[GroupKey, Mapping[str, float]],
) -> str:
    """The groups' table: final and best rate over seeds, plateaus, steps, wall time, levels."""
    lines = [
        f"Plateau: where each seed settled for good, at that level: its last {window} "
        f"evaluations within {eps:g} of their mean, from the first evaluation after which "
        "every one stays within it (a flat stretch before a rise is not a plateau). Trend: "
        "the rise of the least-squares line through the evaluations of each seed's last "
        f"third of steps (at least {TREND_MIN_EVALUATIONS}), ± its standard error; rising "
        "when over that times Student's t (97.5 %, the fit's degrees of freedom).",
        "",
        "| scene, n, algorithm | metric | seeds | final (mean ± sd, min-max) | best | "
        "plateau per seed | trend per seed | steps | wall time (s) | levels |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for key, runs in groups.items():
        finals = [run.series()[1][-1] for run in runs]
        bests = [float(run.series()[1].max()) for run in runs]
        plateaus, ends = [], []
        for run in runs:
            found = final_plateau(*run.series(), window, eps)
            reached = (
                "not flat at the end" if found is None else f"{found.step:,.0f} ({found.level:.2f})"
            )
            plateaus.append(f"s{run.seed}: {reached}")
            fitted = trend(*run.series())
            ends.append(f"s{run.seed}: {'-' if fitted is None else fitted.text()}")
        steps = max(run.rows[-1]["timesteps"] for run in runs)
        wall = max(run.rows[-1]["wall_s"] for run in runs)
        marks = ", ".join(f"{name} {value:.2f}" for name, value in levels.get(key, {}).items())
        lines.append(
            f"| {_group_label(key)} | {runs[0].metric} | {len(runs)} | {_rate_text(finals)} | "
            f"{_rate_text(bests)} | {'; '.join(plateaus)} | {'; '.join(ends)} | "
            f"{steps:,.0f} | {wall:,.0f} | "
            f"{marks or '-'} |"
        )
    return "\n".join(lines) + "\n"


def _chart_png(
    groups: Mapping[GroupKey, Sequence[RunCurve]],
    levels: Mapping[GroupKey, Mapping[str, float]],
) -> bytes:
    """The chart: one row per group, the rate against steps (left) and wall time (right)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(groups), 2, figsize=(11, 3.4 * len(groups)), squeeze=False)
    for row, (key, runs) in enumerate(groups.items()):
        for column, (axis, label) in enumerate(
            zip(AXES, ("env steps", "wall time (s)"), strict=True)
        ):
            ax = axes[row][column]
            if bands_overlap(runs, axis):
                band = seed_band(runs, axis)
                ax.plot(
                    band.x,
                    band.mean,
                    color="C0",
                    label=f"mean of {band.seeds} seeds" if band.seeds > 1 else "one seed",
                )
                if band.seeds > 1:
                    ax.fill_between(
                        band.x,
                        band.low,
                        band.high,
                        color="C0",
                        alpha=0.25,
                        label="min-max over seeds",
                    )
            else:  # no common range, so no mean: each seed on its own
                for k, run in enumerate(runs):
                    x, y = run.series(axis)
                    ax.plot(
                        x, y, color="C0", alpha=1.0 - 0.5 * k / len(runs), label=f"seed {run.seed}"
                    )
            for k, (name, value) in enumerate(levels.get(key, {}).items()):
                ax.axhline(value, color=f"C{k + 1}", linestyle="--", label=f"{name} {value:.2f}")
            ax.set_xlabel(label)
            ax.set_ylabel(f"validation {runs[0].metric.replace('_', ' ')}")
            ax.set_ylim(-0.02, 1.02)
            # A long recipe name (start replay, shaping) would run into the next panel.
            ax.set_title(textwrap.fill(_group_label(key), 52), fontsize=10)
            ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=80)
    plt.close(fig)
    return buffer.getvalue()


def write_problem(out: Path, overwrite: bool) -> str | None:
    """Why :func:`write_learning_curves` would refuse ``out``, or None."""
    return files.outputs_problem(out, (CHART_FILE, TABLE_FILE), overwrite)


def write_learning_curves(
    runs: Sequence[RunCurve],
    out: Path,
    *,
    window: int = 5,
    eps: float = 0.05,
    levels: Mapping[GroupKey, Mapping[str, float]] | None = None,
    overwrite: bool = False,
) -> tuple[Path, Path]:
    """Draw ``out/learning_curves.png`` and write ``out/learning_curves.md``.

    Args:
        runs: The run folders' curves (:func:`read_run`).
        out: The folder.
        window, eps: The plateau rule (the module's docstring).
        levels: Horizontal lines per group (name -> rate: the LQR, the certified ceiling).
        overwrite: Replace earlier files.

    Raises:
        TypeError, ValueError: On a bad ``window`` or ``eps``, no runs, two runs of one
            seed in a group, or an ``out`` that cannot be written (or holds the files
            and ``overwrite`` is false); nothing is written then.
    """
    window, eps = _check_window(window, eps)
    if not runs:
        raise ValueError("no runs to draw")
    problem = write_problem(out, overwrite)
    if problem is not None:
        raise ValueError(problem)
    groups = group_runs(runs)
    levels = levels or {}
    table = markdown_table(groups, window, eps, levels)
    chart = _chart_png(groups, levels)
    out.mkdir(parents=True, exist_ok=True)
    return (
        files.atomic_write_bytes(out / CHART_FILE, chart),
        files.atomic_write_text(out / TABLE_FILE, table),
    )
