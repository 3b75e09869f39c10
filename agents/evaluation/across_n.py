"""The headline rate against the number of trailers: policies, specialists, the LQR and the
certified ceiling on one scene, n by n.

Usage::

    python -m agents.evaluation.across_n --env trailer_env/Reverse-v1 --n 1-6 \\
        --policy dagger_reverse_v1_sequence lqr lqr-adaptive \\
        --specialist dagger_reverse_v1_n{n} --episodes 100 --out docs/generated/across_n

Each ``--policy`` is evaluated on every n it accepts (a model padded to three trailers
refuses four: its cell says so), ``--specialist`` names one model per n (``{n}`` in the
spec, or a list as ``agents.imitate --teacher`` takes:
:class:`agents.policies.teachers.TeacherConfig`), evaluated on its own n where it exists,
and the ceiling is the committed certificate's share of the same starts
(:func:`agents.oracles.certify.ceiling_fraction`). Every cell is the same episodes
(``--episodes`` from ``--seed``, the test seeds by default). Writes ``across_n.md`` (the
table), ``across_n.json`` (every figure) and ``across_n.png`` (the chart) into ``--out``,
atomically; existing files are replaced only with ``--overwrite``.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable, Mapping, Sequence
from functools import partial
from pathlib import Path

from agents.artifacts import files, limits
from agents.artifacts.shipped import resolve_model
from agents.envs import ENV_IDS, HEADLINE_ENV_ID, headline_metric, scene_title
from agents.evaluation.results import evaluate_policies, policy_label
from agents.oracles.certify import ceiling_fraction
from agents.policies.teachers import TeacherConfig
from agents.progress import Progress, duration
from agents.seeds import TEST_SEED
from trailer_env.json_types import JSONObject

OUTPUTS = ("across_n.md", "across_n.json", "across_n.png")
#: The label of the specialists' line (one model per n).
SPECIALIST = "specialist (own n)"
CEILING = "ceiling (certified)"


def parse_counts(text: str) -> list[int]:
    """``"1-6"`` or ``"1,2,4"`` as a sorted list of counts of trailers (1 .. 16)."""
    try:
        if "-" in text:
            low, high = (int(part) for part in text.split("-", 1))
            counts = list(range(low, high + 1))
        else:
            counts = sorted({int(part) for part in text.split(",")})
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected N-M or N,M,...; got {text!r}") from None
    if not counts or counts[0] < 1 or counts[-1] > 16:
        raise argparse.ArgumentTypeError(f"counts of trailers must lie in 1..16; got {text!r}")
    return counts


def specialist_problem(specialist: str | None) -> str | None:
    """Why ``--specialist`` cannot name one model per n (None: it can, or is not given)."""
    if specialist is None:
        return None
    try:
        one_policy = TeacherConfig(specialist).is_one_policy()
    except ValueError as error:
        return str(error)
    return "the spec must hold {n}, e.g. dagger_reverse_v1_n{n}" if one_policy else None


def specialist_of(specialist: str, n: int) -> tuple[str | None, str]:
    """``(spec, "")``: the model ``--specialist`` names for ``n``; ``(None, why)`` when it
    names none, or one that does not exist."""
    try:
        spec = TeacherConfig(specialist).spec(n)
    except ValueError:
        return None, f"no specialist of n = {n} in {specialist}"
    if resolve_model(spec) == spec and not Path(spec).is_file():
        return None, f"no model {spec}"
    return spec, ""


def add_count_options(parser: argparse.ArgumentParser, policies: list[str], out: str) -> None:
    """The options every command drawn n by n takes: --env, --n, --policy, --specialist,
    --out (default ``out/<out>``) and --overwrite."""
    parser.add_argument("--env", default=HEADLINE_ENV_ID, choices=ENV_IDS, metavar="ENV_ID")
    parser.add_argument("--n", type=parse_counts, default=parse_counts("1-6"), help="e.g. 1-6")
    parser.add_argument("--policy", nargs="+", default=policies, metavar="SPEC")
    parser.add_argument(
        "--specialist",
        default=None,
        metavar="SPEC",
        help="one model per n: {n} in the spec, or several comma-separated, each but one "
        "after its counts (1-3=ppo_reverse_v1_n{n},dagger_reverse_v1_n{n})",
    )
    parser.add_argument("--out", type=Path, default=Path("out") / out)
    parser.add_argument("--overwrite", action="store_true", help="replace an earlier run's files")


def check_count_options(
    parser: argparse.ArgumentParser, args: argparse.Namespace, outputs: Sequence[str], episodes: int
) -> None:
    """Exit with status 2 (``parser.error``), before anything runs, on a --specialist that
    names no model per n, a --seed that ``episodes`` would carry past the seeds' range, an
    --out that cannot be written or that holds ``outputs`` without --overwrite."""
    problem = specialist_problem(args.specialist)
    if problem is not None:
        parser.error(f"argument --specialist: {problem}")
    check_out_options(parser, args, outputs, episodes)


def check_out_options(
    parser: argparse.ArgumentParser, args: argparse.Namespace, outputs: Sequence[str], episodes: int
) -> None:
    """Exit with status 2 (``parser.error``), before anything runs, on an --episodes out of
    1 .. MAX_EPISODES, a --seed that ``episodes`` would carry past the seeds' range, or an
    --out that cannot be written or holds ``outputs`` without --overwrite."""
    if not 1 <= episodes <= limits.MAX_EPISODES:
        parser.error(f"argument --episodes: must lie in 1..{limits.MAX_EPISODES}")
    problem = limits.seed_problem(args.seed, episodes) or files.writable_problem(
        args.out, folder=True
    )
    if problem is not None:
        parser.error(f"argument --seed or --out: {problem}")
    existing = [name for name in outputs if (args.out / name).exists()]
    if existing and not args.overwrite:
        parser.error(f"argument --out: {args.out} holds {', '.join(existing)}; pass --overwrite")


def write_outputs(
    out: Path,
    outputs: Sequence[str],
    lines: Mapping[str, Mapping[int, object]],
    fields: JSONObject,
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
    return float(evaluation.summary[metric])


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


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog="python -m agents.evaluation.across_n",
        description="The headline rate against the number of trailers (table, JSON, chart)",
    )
    add_count_options(parser, ["lqr", "lqr-adaptive"], "across_n")
    parser.add_argument("--episodes", type=int, default=100, help="episodes per cell")
    parser.add_argument("--seed", type=int, default=TEST_SEED, help="first episode's seed")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; bad arguments exit with 2 before any episode runs."""
    parser = build_parser()
    args = parser.parse_args(argv)
    check_count_options(parser, args, OUTPUTS, args.episodes)
    started = time.perf_counter()
    lines = rates_across_n(args.env, args.n, args.policy, args.specialist, args.episodes, args.seed)
    seeds = f"seeds {args.seed}..{args.seed + args.episodes - 1}"
    fields: JSONObject = {
        "env_id": args.env,
        "episodes": args.episodes,
        "seed": args.seed,
        "metric": headline_metric(args.env),
    }
    title = f"{scene_title(args.env)}: {args.episodes} episodes per n ({seeds})"
    draw = partial(plot, lines, args.n, title=title)
    write_outputs(args.out, OUTPUTS, lines, fields, markdown(lines, args.n), draw, started)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
