"""The ladder to eight: time to the certified ceiling against the number of trailers.

Each point is one measured training run, read from what the run wrote: a run folder
(``config.json`` and ``evaluations.csv`` of ``agents.train``, ``agents.imitate`` or
``agents.shac``) or a committed model (its card and the curve beside it). Its validation
curve is set against the committed certificate's ceiling at its n
(:attr:`~agents.artifacts.certificates.Certificate.ceiling`):

- the run *reaches* the ceiling at the first evaluation whose headline rate is within
  :data:`GAP_POINTS` points of it, at the wall time that evaluation recorded (training
  with its evaluations; imitation: the planner's labels too), if that is within
  :data:`BUDGET_MINUTES`;
- otherwise its point is the best rate among the evaluations recorded within the budget.

Read with care: the curve's rates are on the run's validation episodes (50 or 100 starts:
a rate near 0.95 on 50 episodes has a standard error of 0.03) and the ceiling on the
certificate's test starts; and each wall time is that of the machine the run trained on,
which its card records (:class:`~agents.artifacts.cards.HostSpeed`; runs trained before
cards recorded it show none). The program: :mod:`agents.commands.ladder`.
"""

from __future__ import annotations

import dataclasses
import statistics
from collections.abc import Sequence
from pathlib import Path
from typing import ClassVar

from agents.artifacts import files
from agents.artifacts.cards import HostSpeed, ModelCard, read_model_card
from agents.artifacts.certificates import committed_certificate
from agents.artifacts.curves import read_curve
from agents.artifacts.paths import curve_path
from agents.artifacts.records import DocumentError, JSONRecord, SparsePart
from agents.artifacts.run_folder import CONFIG_FILE, CURVE_FILE
from agents.envs import headline_metric, scene_title

#: The budget a point is read within, and how close to the ceiling counts as reaching it.
BUDGET_MINUTES = 15.0
GAP_POINTS = 2.0
#: What :func:`write_ladder` writes.
DOCUMENT_FILE, TABLE_FILE, CHART_FILE = "ladder.json", "ladder.md", "ladder.png"
OUTPUTS = (DOCUMENT_FILE, TABLE_FILE, CHART_FILE)


@dataclasses.dataclass(frozen=True)
class LadderPoint(SparsePart):
    """One run against its ceiling (rates in [0, 1], times in seconds of its own run)."""

    method: str
    #: Where it was read from, as given.
    run: str
    env_id: str
    n_trailers: int
    seed: int
    #: The committed certificate's share of its starts (None: no certificate at this n).
    ceiling: float | None
    #: The wall time of the first evaluation within the gap of the ceiling, within the
    #: budget (None: not reached).
    reached_s: float | None
    #: The best rate among the evaluations within the budget, and its wall time.
    best_rate: float
    best_s: float
    #: The wall time of the run's last evaluation (a run may end before the budget).
    last_s: float
    host: HostSpeed | None = None

    @property
    def reached(self) -> bool:
        return self.reached_s is not None


@dataclasses.dataclass(frozen=True)
class Ladder(JSONRecord):
    """``ladder.json``: the points and the rule they were read by."""

    DOCUMENT: ClassVar[str] = "ladder"

    budget_minutes: float
    gap_points: float
    points: tuple[LadderPoint, ...]

    def __post_init__(self) -> None:
        if not self.points:
            raise DocumentError("a ladder needs at least one point")

    @property
    def methods(self) -> list[str]:
        """The methods in the order first given."""
        return list(dict.fromkeys(point.method for point in self.points))

    @property
    def counts(self) -> list[int]:
        return sorted({point.n_trailers for point in self.points})


def _read(source: Path) -> tuple[ModelCard, list[dict[str, float]], str]:
    """A run folder's or a committed model's card and curve, and the curve's metric."""
    if source.is_dir():
        config, curve = source / CONFIG_FILE, source / CURVE_FILE
        if not config.is_file():
            raise ValueError(f"{source} is not a run folder: it has no {CONFIG_FILE}")
        card = ModelCard.from_json(files.read_json(config, "run configuration"), str(config))
    elif source.suffix == ".zip" and source.is_file():
        card, curve = read_model_card(source), curve_path(source)
        if card.empty:
            raise ValueError(f"{source} has no model card")
    else:
        raise ValueError(f"{source} is neither a run folder nor a model (.zip)")
    if not curve.is_file():
        raise ValueError(f"{source} has no learning curve ({curve.name})")
    if card.env_id is None:
        raise ValueError(f"{source}'s card does not name its scene")
    metric = headline_metric(card.env_id)
    return card, read_curve(curve, ("wall_s", metric)), metric


def read_point(method: str, source: Path, budget_minutes: float = BUDGET_MINUTES) -> LadderPoint:
    """The point of one run (see the module docstring).

    Raises:
        ValueError: If ``source`` is neither a run folder nor a model with a card and a
            curve, trained on a range of counts (no one n), or its curve has no row.
    """
    card, rows, metric = _read(source)
    n = card.n_trailers
    if not isinstance(n, int) or n < 1:
        raise ValueError(f"{source} was not trained on one count of trailers (n = {n!r})")
    if not rows:
        raise ValueError(f"{source}'s learning curve has no evaluation")
    assert card.env_id is not None
    certificate = committed_certificate(card.env_id, n)
    ceiling = None if certificate is None else certificate.ceiling
    budget_s = 60.0 * budget_minutes
    timed = sorted((row["wall_s"], row[metric]) for row in rows)
    within = [(wall, rate) for wall, rate in timed if wall <= budget_s] or [(0.0, 0.0)]
    target = None if ceiling is None else ceiling - GAP_POINTS / 100.0
    # Compared as shown: 0.98 under a 1.00 ceiling is within 2 points.
    reached = [wall for wall, rate in within if target is not None and round(rate - target, 9) >= 0]
    best_wall, best_rate = max(within, key=lambda row: (row[1], -row[0]))
    return LadderPoint(
        method=method,
        run=str(source),
        env_id=card.env_id,
        n_trailers=n,
        seed=card.seed if card.seed is not None else 0,
        ceiling=ceiling,
        reached_s=reached[0] if reached else None,
        best_rate=best_rate,
        best_s=best_wall,
        last_s=timed[-1][0],
        host=card.host,
    )


def _minutes(seconds: float) -> str:
    return f"{seconds / 60:.1f}"


def _best(point: LadderPoint) -> str:
    """``52 % at 7.9 min``, or ``0 %`` for a run never safe within the budget."""
    if point.best_rate == 0.0:
        return "0 %"
    return f"{100 * point.best_rate:.0f} % at {_minutes(point.best_s)} min"


def _cell(points: Sequence[LadderPoint]) -> str:
    """``4.1 min (3 of 3)`` when some run reached the ceiling (the median of their times),
    else ``best 16 % (0 of 1)`` (the best of the runs' rates)."""
    if not points:
        return "no run"
    hits = [point.reached_s for point in points if point.reached_s is not None]
    share = f"({len(hits)} of {len(points)})"
    if hits:
        return f"{_minutes(statistics.median(hits))} min {share}"
    return f"best {100 * max(point.best_rate for point in points):.0f} % {share}"


def markdown(ladder: Ladder) -> str:
    """The table (one row per n, one column per method) and the runs with their hosts."""
    methods, counts = ladder.methods, ladder.counts
    scenes = sorted({scene_title(point.env_id) for point in ladder.points})
    lines = [
        f"{', '.join(scenes)}: minutes to within {ladder.gap_points:g} points of the certified "
        f"ceiling (the median over the runs that got there), or the best validation rate "
        f"within {ladder.budget_minutes:g} minutes when none did; (k of m): runs that got "
        "there of the runs measured.",
        "",
        "| n | ceiling | " + " | ".join(methods) + " |",
        "|---|---|" + "---|" * len(methods),
    ]
    for n in counts:
        at_n = [point for point in ladder.points if point.n_trailers == n]
        ceiling = next((p.ceiling for p in at_n if p.ceiling is not None), None)
        cells = [_cell([p for p in at_n if p.method == method]) for method in methods]
        shown = "-" if ceiling is None else f"{100 * ceiling:.0f} %"
        lines.append(f"| {n} | {shown} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "Each run, with the speed of the machine it trained on as its card records it "
        "(`python -m agents.host_speed`'s benchmark when the run started; - where the card "
        "predates the record):",
        "",
        "| method | n | seed | reached at | best within budget | last evaluation | host |",
        "|---|---|---|---|---|---|---|",
    ]
    for point in sorted(ladder.points, key=lambda p: (methods.index(p.method), p.n_trailers)):
        reached = "-" if point.reached_s is None else f"{_minutes(point.reached_s)} min"
        speed = "-" if point.host is None else point.host.cell()
        lines.append(
            f"| {point.method} | {point.n_trailers} | {point.seed} | {reached} "
            f"| {_best(point)} "
            f"| {_minutes(point.last_s)} min | {speed} |"
        )
    return "\n".join(lines) + "\n"


def draw(ladder: Ladder, out: Path) -> Path:
    """The chart: minutes to the ceiling (top; runs that got there) and the best rate within
    the budget (bottom; every run, the ceiling dashed) against n, one colour per method."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from agents.evaluation.plots import save_page_figure

    methods, counts = ladder.methods, ladder.counts
    fig, (top, bottom) = plt.subplots(
        2, 1, figsize=(8.0, 6.5), sharex=True, layout="constrained", height_ratios=(1, 1.2)
    )
    width = 0.5 / max(len(methods), 1)
    for index, method in enumerate(methods):
        offset = (index - (len(methods) - 1) / 2) * width
        mine = [point for point in ladder.points if point.method == method]
        color = f"C{index}"
        hits = [point for point in mine if point.reached_s is not None]
        top.scatter(
            [p.n_trailers + offset for p in hits],
            [(p.reached_s or 0.0) / 60 for p in hits],
            color=color,
            label=method,
            zorder=3,
        )
        bottom.scatter(
            [p.n_trailers + offset for p in mine],
            [100 * p.best_rate for p in mine],
            color=color,
            marker="o",
            label=method,
            zorder=3,
        )
    ceilings = {p.n_trailers: p.ceiling for p in ladder.points if p.ceiling is not None}
    xs = sorted(ceilings)
    bottom.plot(xs, [100 * ceilings[n] for n in xs], "--", color="0.3", label="ceiling")
    top.axhline(ladder.budget_minutes, color="0.5", lw=1, ls=":")
    top.set_ylim(0, ladder.budget_minutes * 1.05)
    top.set_ylabel(f"minutes to within {ladder.gap_points:g} pts")
    bottom.set_ylim(-3, 103)
    bottom.set_ylabel(f"best validation % within {ladder.budget_minutes:g} min")
    bottom.set_xlabel("trailers n")
    bottom.set_xticks(counts)
    bottom.legend(fontsize=8, loc="center right")
    for axis in (top, bottom):
        axis.grid(alpha=0.3)
    scenes = ", ".join(sorted({scene_title(point.env_id) for point in ladder.points}))
    top.set_title(f"{scenes}: time to the certified ceiling, one point per run", fontsize=11)
    return save_page_figure(fig, plt, out)


def write_problem(out: Path, overwrite: bool) -> str | None:
    """Why :func:`write_ladder` would refuse ``out`` (None: it would not)."""
    return files.outputs_problem(out, OUTPUTS, overwrite)


def write_ladder(ladder: Ladder, out: Path, *, overwrite: bool = False) -> tuple[Path, ...]:
    """Write ``ladder.json``, ``ladder.md`` and ``ladder.png`` into ``out``, atomically.

    Raises:
        ValueError: If ``out`` cannot be written or holds them and ``overwrite`` is false
            (nothing is written then).
    """
    problem = write_problem(out, overwrite)
    if problem is not None:
        raise ValueError(problem)
    out.mkdir(parents=True, exist_ok=True)
    return (
        files.write_json(out / DOCUMENT_FILE, ladder.to_json()),
        files.atomic_write_text(out / TABLE_FILE, markdown(ladder)),
        draw(ladder, out / CHART_FILE),
    )


def read_ladder(out: Path) -> Ladder:
    """``out/ladder.json``, checked whole.

    Raises:
        ValueError: If it is missing or not a ladder.
    """
    path = out / DOCUMENT_FILE
    return Ladder.from_json(files.read_json(path, "ladder"), str(path))
