"""The leaderboard in pictures: who stands where, per scene and number of trailers.

One panel per scenario (a :class:`~agents.artifacts.results.ResultsDocument`): every
policy's headline rate (safe episodes on Reverse, successful ones elsewhere) as a dot with
its 95 % Wilson interval, against two lines, the certified ceiling (the share of the
episodes' starts that the committed certificate proves feasible) and the LQR. The oracles
are the baselines whose record has an oracle note
(:class:`agents.policies.baselines.Baseline`). The headline scene comes first
(:data:`agents.envs.HEADLINE_ENV_ID`), then the scene table's order, then n.
``python -m agents.report`` writes it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from agents.artifacts.results import PolicyResult, ResultsDocument
from agents.envs import ENV_IDS, headline_metric, scene_title
from agents.evaluation.ceiling import ceiling_fraction
from agents.evaluation.metrics import wilson_interval
from agents.policies.baselines import BASELINES

if TYPE_CHECKING:
    from matplotlib.axes import Axes

#: Dot colours by kind of policy: the learned agents stand out, the oracles are marked.
KIND_COLOURS = {"learned": "#d95f02", "oracle": "#7570b3", "lqr": "#1f78b4", "other": "#888888"}

#: Where the rates are written (the x axis is in %).
RATE_COLUMN = 106.0

#: The leaderboard's text size in points at :data:`agents.evaluation.plots.PAGE_DPI` (the
#: rates beside the dots and the axis one point less, the small picture's one point less
#: again): the picture is as wide as the site's column, so the page shows it at 100 %.
LEADERBOARD_FONT_PT = 10

#: The baseline drawn as a line beside the ceiling.
LQR = "lqr"


@dataclass(frozen=True)
class Standing:
    """One policy in one scenario: its headline rate and its 95 % Wilson interval."""

    name: str
    kind: str  # a key of KIND_COLOURS
    rate: float
    low: float
    high: float


@dataclass(frozen=True)
class Panel:
    """One scenario: its standings (in the results' order), the ceiling and the LQR's rate."""

    env_id: str
    n_trailers: int
    metric: str
    standings: tuple[Standing, ...]
    ceiling: float | None
    lqr: float | None

    @property
    def title(self) -> str:
        """ "Reverse-v1, n = 2"."""
        return f"{scene_title(self.env_id)}, n = {self.n_trailers}"


def _kind(policy: PolicyResult) -> str:
    """The policy's key of :data:`KIND_COLOURS`: oracles (they read the exact state, not
    comparable to a policy, shown for the ceiling) are the baselines with an oracle note."""
    if policy.kind != "baseline":
        return "learned"
    baseline = BASELINES.get(policy.name)
    if baseline is not None and baseline.oracle_note is not None:
        return "oracle"
    return "lqr" if policy.name == LQR else "other"


def panel_of(document: ResultsDocument) -> Panel:
    """The panel of one results document.

    Raises:
        ValueError: If the document's ``n_trailers`` is not one count.
    """
    n = document.n_trailers
    if not isinstance(n, int):
        raise ValueError(f"a leaderboard panel needs one count of trailers, got {n!r}")
    metric = headline_metric(document.env_id)
    standings = []
    lqr = None
    for policy in document.policies:
        rate = policy.summary.rate(metric)
        low, high = wilson_interval(round(rate * document.episodes), document.episodes)
        standings.append(Standing(policy.name, _kind(policy), rate, low, high))
        if policy.name == LQR:
            lqr = rate
    ceiling = ceiling_fraction(document.env_id, n, document.episodes, document.seeds[0])
    return Panel(document.env_id, n, metric, tuple(standings), ceiling, lqr)


def ordered(panels: Sequence[Panel], headline_env: str) -> list[Panel]:
    """``panels`` with ``headline_env``'s first, then in the scene table's order, then by n."""

    def key(panel: Panel) -> tuple[int, int, int]:
        scene = ENV_IDS.index(panel.env_id) if panel.env_id in ENV_IDS else len(ENV_IDS)
        return (panel.env_id != headline_env, scene, panel.n_trailers)

    return sorted(panels, key=key)


def _draw_panel(axis: Axes, panel: Panel, *, small: bool = False) -> None:
    names = [standing.name for standing in panel.standings]
    rows = range(len(names))
    font = LEADERBOARD_FONT_PT - (1 if small else 0)
    if panel.ceiling is not None:
        axis.axvline(100 * panel.ceiling, color="#1b9e77", lw=2, ls="--")
        axis.text(
            100 * panel.ceiling - 1.5,
            -0.7,
            f"ceiling {100 * panel.ceiling:.0f}%",
            color="#1b9e77",
            ha="right",
            va="center",
            fontsize=font - 1,
        )
    if panel.lqr is not None:
        axis.axvline(100 * panel.lqr, color=KIND_COLOURS["lqr"], lw=1, ls=":")
    for row, standing in zip(rows, panel.standings, strict=True):
        colour = KIND_COLOURS[standing.kind]
        axis.plot(
            [100 * standing.low, 100 * standing.high],
            [row, row],
            color=colour,
            lw=2.5,
            alpha=0.45,
            solid_capstyle="butt",
        )
        axis.plot(100 * standing.rate, row, "o", color=colour, ms=6 if small else 7)
        # The rates stand in a column right of 100 %, clear of the dots and lines.
        axis.text(
            RATE_COLUMN,
            row,
            f"{100 * standing.rate:.0f}%",
            va="center",
            ha="left",
            fontsize=font - 1,
            color=colour,
        )
    axis.set_yticks(list(rows))
    axis.set_yticklabels(names, fontsize=font)
    for label, standing in zip(axis.get_yticklabels(), panel.standings, strict=True):
        label.set_color(KIND_COLOURS[standing.kind] if standing.kind != "other" else "#333333")
        if standing.kind == "learned":
            label.set_fontweight("bold")
    axis.set_ylim(len(names) - 0.4, -1.0)
    axis.set_xlim(-2, RATE_COLUMN + 14)
    axis.axvspan(RATE_COLUMN - 2, RATE_COLUMN + 14, color="#f4f4f4", zorder=0)
    axis.set_xticks([0, 25, 50, 75, 100])
    axis.tick_params(axis="x", labelsize=font - 1)
    axis.grid(axis="x", alpha=0.3)
    what = "safe" if panel.metric == "safe_rate" else "successful"
    axis.set_title(f"{panel.title}: {what} %", fontsize=font + 1)


def plot_leaderboard(
    panels: Sequence[Panel], out: Path, *, columns: int = 2, title: str = "", small: bool = False
) -> Path:
    """Draw ``panels`` (in their order) in a grid of ``columns``; write ``out`` atomically.

    The picture is :data:`agents.evaluation.plots.PAGE_WIDTH_PX` wide whatever
    ``columns`` (the site shows it at 100 %: no text under 8 pt, 11 px); more columns
    make narrower panels.

    Raises:
        ValueError: If there are no panels or ``columns`` < 1.
    """
    from agents.artifacts import files
    from agents.evaluation.plots import PAGE_DPI, PAGE_WIDTH_PX, _pyplot

    if not panels:
        raise ValueError("no panels to draw")
    if columns < 1:
        raise ValueError(f"columns must be >= 1, got {columns}")
    plt = _pyplot()
    columns = min(columns, len(panels))
    count = -(-len(panels) // columns)
    tallest = max(len(panel.standings) for panel in panels)
    height = 0.7 + 0.3 * tallest
    fig, axes = plt.subplots(
        count,
        columns,
        figsize=(PAGE_WIDTH_PX / PAGE_DPI, height * count),
        squeeze=False,
        layout="constrained",
    )
    for index, axis in enumerate(axes.flat):
        if index < len(panels):
            _draw_panel(axis, panels[index], small=small)
        else:
            axis.axis("off")
    handles = [
        plt.Line2D([], [], color="#1b9e77", ls="--", lw=2, label="certified ceiling"),
        plt.Line2D([], [], color=KIND_COLOURS["lqr"], ls=":", lw=1, label="LQR"),
        plt.Line2D([], [], color=KIND_COLOURS["learned"], marker="o", ls="", label="learned"),
        plt.Line2D(
            [], [], color=KIND_COLOURS["oracle"], marker="o", ls="", label="oracle (exact state)"
        ),
        plt.Line2D(
            [],
            [],
            color=KIND_COLOURS["other"],
            marker="o",
            lw=2.5,
            alpha=0.6,
            label="baseline, 95% interval",
        ),
    ]
    font = LEADERBOARD_FONT_PT - (1 if small else 0)
    # Five entries do not fit one line of the column at this size: three, then two.
    fig.legend(handles=handles, loc="outside lower center", ncol=3, frameon=False, fontsize=font)
    if title:
        fig.suptitle(title, fontsize=font + 2)
    out.parent.mkdir(parents=True, exist_ok=True)
    with files.replacing(out) as temporary:
        fig.savefig(temporary, dpi=100)
    plt.close(fig)
    return out
