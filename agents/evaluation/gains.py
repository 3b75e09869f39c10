"""The gains a policy applies at the straight convoy, trailer by trailer, n by n (the
program: :mod:`agents.commands.gains`).

Near the straight convoy a stabilising policy acts about linearly on the hitch angles, so
its gains ``g_k = d action / d alpha_k`` (k = 1 the trailer behind the cart) say what it
has learned about each trailer, and they can be compared with the linear regulator's
(whose gains come from the model's Riccati equation at every n) and across n. Each gain is
a central difference (``alpha_k = +-`` :data:`STEP` rad, one at a time) of the policy's
action on one observation: the start of a seed of the scene with every hitch angle set to
zero, the rest (speed, turning rate, mass, task) as it started. A policy that stabilises
the convoy at n has gains of alternating sign whose size grows with n; what a policy
trained on fewer trailers does at an n it never saw is read off its row.

Policy specs are evaluated at every n they accept (a cell says why when refused); a
specialist spec names one model per n as :mod:`agents.evaluation.across_n` takes it. The
outputs: ``gains.md`` (one table per n), ``gains.json`` (every gain) and ``gains.png``
(one panel per n, gain against trailer).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from agents.artifacts import files
from agents.envs import make_vector_env, scene_title
from agents.evaluation.across_n import SPECIALIST, specialist_of
from agents.evaluation.results import policy_label
from agents.policies.registry import load_policy
from agents.progress import Progress
from trailer_env.observation import flat_observation

OUTPUTS = ("gains.md", "gains.json", "gains.png")
#: The hitch-angle step of the central differences (rad): small enough that every policy
#: here is linear over it (the LQR's, linear up to its clip, are its design's times one
#: factor to about 1e-7; the test allows 1e-3), large enough that float32
#: observations resolve it.
STEP = 1e-3

#: Line label -> n -> the gains (one per trailer), or why the cell is empty.
Gains = dict[str, dict[int, list[float] | str]]


def straight_observations(env_id: str, n: int, seed: int) -> np.ndarray:
    """The flat observations ``(1 + 2n, obs_dim)`` whose actions give the gains at ``n``:
    the start ``seed`` with every hitch angle zero, then, for each trailer k, that
    observation with ``alpha_k = +STEP`` and ``alpha_k = -STEP``.

    The flat layout holds ``sin alpha_k`` at column ``1 + k`` and ``cos alpha_k`` at
    ``1 + n + k`` (k = 1..n; :mod:`trailer_env.observation`).
    """
    envs = make_vector_env(env_id, 1, {"n_trailers": n})
    try:
        start, _ = envs.reset(seed=seed)
    finally:
        envs.close()
    straight = flat_observation(start, "gains")[0].astype(np.float32)
    sines, cosines = slice(2, 2 + n), slice(2 + n, 2 + 2 * n)
    straight[sines], straight[cosines] = 0.0, 1.0
    rows = [straight]
    for k in range(n):
        for sign in (1.0, -1.0):
            row = straight.copy()
            row[sines.start + k] = np.sin(sign * STEP)
            row[cosines.start + k] = np.cos(STEP)
            rows.append(row)
    return np.stack(rows)


def policy_gains(spec: str, env_id: str, n: int, seed: int) -> list[float]:
    """``d action / d alpha_k`` (k = 1..n) of the policy ``spec`` at the straight convoy.

    Raises:
        ValueError: If the policy refuses this n, or acts with more than one action.
    """
    policy = load_policy(spec, env_id, {"n_trailers": n})
    actions = np.asarray(policy(straight_observations(env_id, n, seed)), dtype=np.float64)
    if actions.ndim != 2 or actions.shape[1] != 1:
        raise ValueError(f"gains need one action, {spec} gives {actions.shape[1:]}")
    plus, minus = actions[1::2, 0], actions[2::2, 0]
    return ((plus - minus) / (2.0 * STEP)).tolist()


def gains_across_n(
    env_id: str, counts: Sequence[int], policies: Sequence[str], specialist: str | None, seed: int
) -> Gains:
    """Every line's gains at every n (:data:`Gains`)."""
    lines: Gains = {policy_label(spec): {} for spec in policies}
    if specialist is not None:
        lines[SPECIALIST] = {}
    with Progress(len(counts), f"{scene_title(env_id)} gains") as bar:
        for n in counts:
            for spec in policies:
                lines[policy_label(spec)][n] = _cell(spec, env_id, n, seed)
            if specialist is not None:
                own, missing = specialist_of(specialist, n)
                lines[SPECIALIST][n] = missing if own is None else _cell(own, env_id, n, seed)
            bar.advance(f"n = {n}")
    return lines


def _cell(spec: str, env_id: str, n: int, seed: int) -> list[float] | str:
    try:
        return policy_gains(spec, env_id, n, seed)
    except ValueError as error:  # a model built for other counts refuses this one
        return f"refused: {str(error).splitlines()[0][:80]}"


def markdown(lines: Gains, counts: Sequence[int]) -> str:
    """One table per n: a row per line, a column per trailer (gains to 3 significant digits)."""
    parts = []
    for n in counts:
        header = f"n = {n}\n\n| policy | " + " | ".join(f"g_{k}" for k in range(1, n + 1)) + " |"
        rows = [header, "|---|" + "---|" * n]
        for label, cells in lines.items():
            cell = cells[n]
            values = [f"{g:.3g}" for g in cell] if isinstance(cell, list) else ["-"] * n
            rows.append(f"| {label} | " + " | ".join(values) + " |")
        parts.append("\n".join(rows) + "\n")
    return "\n".join(parts)


def plot(lines: Gains, counts: Sequence[int], out: Path, title: str) -> Path:
    """One panel per n (its own scale): each line's gain against the trailer."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    columns = min(3, len(counts))
    rows = -(-len(counts) // columns)
    fig, axes = plt.subplots(
        rows, columns, figsize=(4.2 * columns, 3.2 * rows), layout="constrained", squeeze=False
    )
    for axis, n in zip(axes.flat, counts, strict=False):
        for index, (label, cells) in enumerate(lines.items()):
            cell = cells[n]
            if isinstance(cell, list):
                trailers = np.arange(1, n + 1)
                axis.plot(trailers, cell, marker="o", label=label, color=f"C{index}")
        axis.axhline(0.0, color="0.6", lw=0.8)
        axis.set_xticks(range(1, n + 1))
        axis.set_title(f"n = {n}", fontsize=10)
        axis.set_xlabel("trailer k (1: behind the cart)")
        axis.set_ylabel("d action / d alpha_k")
        axis.grid(alpha=0.3)
    for axis in list(axes.flat)[len(counts) :]:
        axis.set_visible(False)
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=min(4, len(labels)), fontsize=8)
    fig.suptitle(title, fontsize=11)
    with files.replacing(out) as temporary:
        fig.savefig(temporary, dpi=90)
    plt.close(fig)
    return out
