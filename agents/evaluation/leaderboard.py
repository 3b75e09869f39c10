"""The leaderboard in pictures: who stands where, per scene and number of trailers.

One panel per scenario (a results document of :func:`agents.evaluation.results.results_document`):
every policy's headline rate (safe episodes on Reverse, successful ones elsewhere) as a
dot with its 95 % Wilson interval, against two lines, the certified ceiling (the share of
the episodes' starts that the committed certificate proves feasible) and the LQR. The
headline scene comes first (:data:`agents.evaluation.report.HEADLINE`'s scene), then the
scene table's order, then n. ``python -m agents.report`` writes it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from agents.envs import ENV_IDS, headline_metric, scene_title
from agents.evaluation.metrics import wilson_interval
from agents.oracles.certify import ceiling_fraction

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

#: Oracles: they read the exact state (not comparable to a policy, shown for the ceiling).
ORACLES = frozenset({"mpc", "mpc-replay", "ilqr"})


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


def _kind(policy: Mapping[str, Any]) -> str:
    if policy["kind"] in ("model", "callable"):
        return "learned"
    if policy["name"] in ORACLES:
        return "oracle"
    return "lqr" if policy["name"] == "lqr" else "other"


def panel_of(document: Mapping[str, Any]) -> Panel:
    """The panel of one results document (``results_document``'s dict, as in results.json).

    Raises:
        KeyError: If the document lacks a field results_document writes.
    """
    env_id = str(document["env_id"])
    n = int(document["env_kwargs"]["n_trailers"])
    episodes = int(document["episodes"])
    metric = headline_metric(env_id)
    standings = []
    lqr = None
    for policy in document["policies"]:
        rate = float(policy[metric])
        low, high = wilson_interval(round(rate * episodes), episodes)
        standings.append(Standing(str(policy["name"]), _kind(policy), rate, low, high))
        if policy["name"] == "lqr":
            lqr = rate
    ceiling = ceiling_fraction(env_id, n, episodes, int(document["seeds"][0]))
    return Panel(env_id, n, metric, tuple(standings), ceiling, lqr)


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
