"""Why a SHAC run loses what it learned, in one chart (:mod:`agents.training.shac`).

Each run's ``evaluations.csv`` holds, at every validation, the rate of the actor's mean
action (``safe_rate``), of the same actor acting with its exploration noise as in the
windows it learns from (``sampled_safe_rate``) and the share of those windows' mean
actions past the rail's bounds (``saturated_share``). The chart draws the two rates
(top) and the share (bottom) against the windows trained, one colour per run.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agents.artifacts import files
from agents.artifacts.curves import read_curve
from agents.artifacts.run_folder import CURVE_FILE

#: The columns the chart reads.
COLUMNS = ("iteration", "safe_rate", "sampled_safe_rate", "saturated_share")


@dataclass(frozen=True)
class SHACCurve:
    """One run's validations.

    Attributes:
        label: The run folder's name.
        iteration: Windows trained at each validation.
        safe_rate: The mean action's safe share of the validation starts.
        sampled_safe_rate: The same with the actor's exploration noise.
        saturated_share: The share of the window's mean actions past the bounds.
    """

    label: str
    iteration: np.ndarray
    safe_rate: np.ndarray
    sampled_safe_rate: np.ndarray
    saturated_share: np.ndarray


def read_shac_curve(run_dir: Path) -> SHACCurve:
    """Read a SHAC run folder's ``evaluations.csv``, checked whole.

    Raises:
        ValueError: If it has no rows, lacks a column of :data:`COLUMNS` (a run older
            than those columns), or a rate or share lies outside [0, 1].
    """
    rows = read_curve(Path(run_dir) / CURVE_FILE, COLUMNS)
    if not rows:
        raise ValueError(f"{run_dir}: no {CURVE_FILE} rows (not a SHAC run folder?)")
    columns = {name: np.array([row[name] for row in rows]) for name in COLUMNS}
    for name in COLUMNS[1:]:
        if not np.all((columns[name] >= 0.0) & (columns[name] <= 1.0)):
            raise ValueError(f"{run_dir}: {name} outside [0, 1] in {CURVE_FILE}")
    return SHACCurve(label=Path(run_dir).name, **columns)


def shac_chart_png(curves: Sequence[SHACCurve]) -> bytes:
    """The chart as PNG bytes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (rates, share) = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    for k, curve in enumerate(curves):
        color = f"C{k}"
        rates.plot(curve.iteration, curve.safe_rate, color=color, label=f"{curve.label}: mean")
        rates.plot(
            curve.iteration,
            curve.sampled_safe_rate,
            color=color,
            linestyle=":",
            label=f"{curve.label}: with its noise",
        )
        share.plot(curve.iteration, curve.saturated_share, color=color, label=curve.label)
    rates.set_ylabel("validation safe rate")
    rates.set_ylim(-0.02, 1.02)
    rates.legend(fontsize=7, loc="upper left")
    rates.set_title("SHAC: the mean action and the noisy actor it learns from", fontsize=10)
    share.set_ylabel("mean actions past the bounds")
    share.set_ylim(-0.02, 1.02)
    share.set_xlabel("windows trained")
    share.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=80)
    plt.close(fig)
    return buffer.getvalue()


def write_shac_chart(curves: Sequence[SHACCurve], out: Path) -> Path:
    """Write the chart of ``curves`` to ``out`` atomically; returns ``out``."""
    if not curves:
        raise ValueError("no runs to chart")
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    return files.atomic_write_bytes(Path(out), shac_chart_png(curves))


__all__ = ["COLUMNS", "SHACCurve", "read_shac_curve", "shac_chart_png", "write_shac_chart"]
