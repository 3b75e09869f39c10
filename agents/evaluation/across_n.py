"""The headline rate against the number of trailers: policies, specialists, the LQR and the
certified ceiling on one scene, n by n (the program: :mod:`agents.commands.across_n`).

Each policy is evaluated on every n it accepts (a model padded to three trailers refuses
four: its cell says so), a specialist spec names one model per n (``{n}`` in the spec, or
a list as ``agents.imitate --expert-policy`` takes:
:class:`agents.policies.experts.PolicyExpertConfig`), evaluated on its own n where it exists,
and the ceiling is the committed certificate's share of the same starts
(:func:`agents.evaluation.ceiling.ceiling_fraction`). Every cell is the same episodes.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from agents.artifacts import files
from agents.artifacts.shipped import resolve_model
from agents.envs import headline_metric, scene_title
from agents.evaluation.ceiling import ceiling_fraction
from agents.evaluation.results import evaluate_policies, policy_label
from agents.policies.experts import PolicyExpertConfig
from agents.progress import Progress, duration

OUTPUTS = ("across_n.md", "across_n.json", "across_n.png")
#: The label of the specialists' line (one model per n).
SPECIALIST = "specialist (own n)"
CEILING = "ceiling (certified)"


def specialist_problem(specialist: str | None) -> str | None:
    """Why ``--specialist`` cannot name one model per n (None: it can, or is not given)."""
    if specialist is None:
        return None
    try:
        one_policy = PolicyExpertConfig(specialist).is_one_policy()
    except ValueError as error:
        return str(error)
    return "the spec must hold {n}, e.g. dagger_reverse_v1_n{n}" if one_policy else None


def specialist_of(specialist: str, n: int) -> tuple[str | None, str]:
    """``(spec, "")``: the model ``--specialist`` names for ``n``; ``(None, why)`` when it
    names none, or one that does not exist."""
    try:
        spec = PolicyExpertConfig(specialist).spec(n)
    except ValueError:
        return None, f"no specialist of n = {n} in {specialist}"
    if resolve_model(spec) == spec and not Path(spec).is_file():
        return None, f"no model {spec}"
    return spec, ""


def write_outputs(
    out: Path,
    outputs: Sequence[str],
    lines: Mapping[str, Mapping[int, object]],
    fields: Mapping[str, object],
    table: str,
    draw: Callable[[Path], object],
    started: float,
) -> None:
    """Write the table, the JSON (``fields`` and every line's cells by n) and the chart
    (``outputs``, in that order) atomically into ``out``, then print the table and what
    was written since ``started``."""
    out.mkdir(parents=True, exist_ok=True)
    files.atomic_write_text(out / outputs[0], table)
    by_n = {label: {str(n): value for n, value in cells.items()} for label, cells in lines.items()}
    files.write_json(out / outputs[1], {**fields, "lines": by_n})
    draw(out / outputs[2])
    print(table, end="")
    print(
        f"wrote {', '.join(str(out / name) for name in outputs)} in "
        f"{duration(time.perf_counter() - started)}"
    )


def rates_across_n(
    env_id: str,
    counts: Sequence[int],
    policies: Sequence[str],
    specialist: str | None,
    episodes: int,
    seed: int,
) -> dict[str, dict[int, float | str]]:
    """Line label -> n -> headline rate in [0, 1], or the reason the cell is empty."""
    metric = headline_metric(env_id)
    lines: dict[str, dict[int, float | str]] = {policy_label(spec): {} for spec in policies}
    if specialist is not None:
        lines[SPECIALIST] = {}
    lines[CEILING] = {}
    with Progress(len(counts), f"{scene_title(env_id)} across n") as bar:
        for n in counts:
            kwargs = {"n_trailers": n}
            for spec in policies:
                lines[policy_label(spec)][n] = _rate(spec, env_id, kwargs, episodes, seed, metric)
            if specialist is not None:
                own, missing = specialist_of(specialist, n)
                lines[SPECIALIST][n] = (
                    missing if own is None else _rate(own, env_id, kwargs, episodes, seed, metric)
                )
            ceiling = ceiling_fraction(env_id, n, episodes, seed)
            lines[CEILING][n] = "not certified" if ceiling is None else ceiling
            bar.advance(f"n = {n}")
    return lines


def _rate(
    spec: str, env_id: str, kwargs: dict[str, int], episodes: int, seed: int, metric: str
) -> float | str:
    try:
        (evaluation,) = evaluate_policies(
            [spec], env_id, kwargs, episodes, seed, with_seeds=False, progress=False
        )
    except ValueError as error:
        # A policy built for other counts of trailers refuses this one: an empty cell.
        return f"refused: {str(error).splitlines()[0][:80]}"
    return evaluation.summary.rate(metric)


def markdown(lines: dict[str, dict[int, float | str]], counts: Sequence[int]) -> str:
    """The table: one row per line, one column per n (rates in %, "-" for an empty cell)."""
    header = "| policy | " + " | ".join(f"n = {n}" for n in counts) + " |"
    rows = [header, "|---|" + "---|" * len(counts)]
    for label, cells in lines.items():
        values = [
            f"{100 * value:.0f}" if isinstance(value, float) else "-"
            for value in (cells[n] for n in counts)
        ]
        rows.append(f"| {label} | " + " | ".join(values) + " |")
    return "\n".join(rows) + "\n"


def plot(
    lines: dict[str, dict[int, float | str]], counts: Sequence[int], out: Path, title: str
) -> Path:
    """The chart: the headline rate against n, one line per policy, the ceiling dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axis = plt.subplots(figsize=(8.0, 4.5), layout="constrained")
    for label, cells in lines.items():
        xs = [n for n in counts if isinstance(cells[n], float)]
        ys = [100 * float(cells[n]) for n in xs]
        if not xs:
            continue
        style = {"ls": "--", "color": "#1b9e77", "lw": 2} if label == CEILING else {"marker": "o"}
        axis.plot(xs, ys, label=label, **style)
    axis.set_xticks(list(counts))
    axis.set_xlabel("trailers n")
    axis.set_ylabel("safe episodes %")
    axis.set_ylim(-3, 103)
    axis.grid(alpha=0.3)
    axis.legend(fontsize=9, loc="lower left")
    axis.set_title(title, fontsize=11)
    with files.replacing(out) as temporary:
        fig.savefig(temporary, dpi=100)
    plt.close(fig)
    return out
