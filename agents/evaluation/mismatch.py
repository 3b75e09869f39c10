"""How far the policies stretch: the certified ceiling and every policy's safe rate against
the size of the parameter mismatch, and the parameter that matters most at each n (the
program: :mod:`agents.commands.mismatch`).

A size ``s`` % draws M, J0, a, l and mu per episode uniformly in ``1 +- s / 100`` of
nominal (the preset ``mismatch<s>`` of :data:`trailer_env.randomize.PRESETS`; 0 is the
nominal physics). At each n and size every policy (a spec with ``{n}``: the model of
that count, where one is committed) plays the test starts (the ones the
committed certificate covers: ``reverse_v1_n<n>.json`` at 0, else
``reverse_v1_mismatch<s>_n<n>.json``) and as many fresh ones
(:data:`agents.seeds.FRESH_SEED`); a model with a memory plays in an env with its
window (``history`` on its card), the others in the plain env. Then each parameter alone
is drawn in ``1 +- SENSITIVITY_SIZE / 100`` and the policies' rates on the test starts
show which one costs them most.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from agents.artifacts import files
from agents.artifacts.certificates import OPEN
from agents.envs import HEADLINE_ENV_ID, scene_title
from agents.evaluation.ceiling import ceiling_fraction, status_count
from agents.evaluation.results import evaluate_policies
from agents.policies.registry import is_model_spec, policy_label, window_kwargs
from agents.progress import Progress
from agents.seeds import FRESH_SEED, TEST_SEED

ENV_ID = HEADLINE_ENV_ID
#: Mismatch sizes, % (0: nominal physics).
SIZES = (0, 10, 20, 30, 40)
#: The parameters a preset draws, in the order of the sensitivity table.
MISMATCHED = ("M", "J0", "a", "l", "mu")
#: The size, %, each parameter is drawn alone with in the sensitivity table.
SENSITIVITY_SIZE = 40
#: The default policies; ``{n}`` is the count's.
POLICIES = (
    "lqr",
    "lqr-adaptive",
    "lqr-estimated",
    "ppo_reverse_v1_n{n}",
    "dagger_reverse_v1_general",
    "dagger_reverse_v1_memory",
    "ppo_reverse_v1_memory_n{n}",
    "dagger_reverse_v1_adapt_n{n}",
)
OUTPUTS = ("mismatch.md", "mismatch.json", *(f"mismatch_n{n}.png" for n in (1, 2, 3)))


def preset(size: int) -> str | None:
    """The ``randomize`` preset of a size (None: nominal)."""
    return None if size == 0 else f"mismatch{size}"


def env_kwargs(spec: str, n: int, randomize: object) -> dict[str, object]:
    """The env a policy plays: ``n`` trailers, the physics, and a model's memory window."""
    kwargs: dict[str, object] = {"n_trailers": n}
    if randomize is not None:
        kwargs["randomize"] = randomize
    return window_kwargs(spec, kwargs)


def safe_rate(spec: str, n: int, randomize: object, episodes: int, seed: int) -> float:
    """``spec``'s safe rate on ``episodes`` episodes from ``seed``."""
    kwargs = env_kwargs(spec, n, randomize)
    (evaluation,) = evaluate_policies(
        [spec], ENV_ID, kwargs, episodes, seed, with_seeds=False, progress=False
    )
    return float(evaluation.summary.safe_rate)


@dataclass
class CountSweep:
    """One n's figures: per size the ceiling and each policy's (test, fresh) safe rate; per
    parameter drawn alone, each policy's test rate."""

    n: int
    policies: list[str]
    ceiling: dict[int, float | None] = field(default_factory=dict)
    #: Per size, the test starts the certificate leaves open (the ceiling is a lower bound).
    open: dict[int, int | None] = field(default_factory=dict)
    rates: dict[int, dict[str, tuple[float, float]]] = field(default_factory=dict)
    alone: dict[str, dict[str, float]] = field(default_factory=dict)

    def most_costly(self) -> str:
        """The parameter whose mismatch alone costs the policies that do not read the
        parameters most (the mean drop of their test rate from nominal)."""
        blind = [label for label in self.policies if label != "lqr-adaptive"]

        def drop(name: str) -> float:
            return sum(self.rates[0][label][0] - self.alone[name][label] for label in blind)

        return max(self.alone, key=drop)


def sweep_count(
    n: int,
    specs: Sequence[str],
    sizes: Sequence[int],
    episodes: int,
    seed: int,
    fresh_seed: int,
    bar: Progress | None = None,
) -> CountSweep:
    """Measure one n (see the module docstring); ``bar`` advances once per size and per
    parameter drawn alone."""
    # A spec with {n} names one model per count: a count without its model is left out.
    resolved = [
        spec.replace("{n}", str(n))
        for spec in specs
        if "{n}" not in spec or is_model_spec(spec.replace("{n}", str(n)))
    ]
    labels = [policy_label(spec) for spec in resolved]
    found = CountSweep(n, labels)
    for size in sizes:
        randomize = preset(size)
        found.ceiling[size] = ceiling_fraction(ENV_ID, n, episodes, seed, randomize=randomize)
        found.open[size] = status_count(OPEN, ENV_ID, n, episodes, seed, randomize=randomize)
        found.rates[size] = {
            label: (
                safe_rate(spec, n, randomize, episodes, seed),
                safe_rate(spec, n, randomize, episodes, fresh_seed),
            )
            for spec, label in zip(resolved, labels, strict=True)
        }
        if bar is not None:
            bar.advance(f"n = {n}, {size} %")
    if 0 not in found.rates:
        return found
    low, high = 1.0 - SENSITIVITY_SIZE / 100, 1.0 + SENSITIVITY_SIZE / 100
    for name in MISMATCHED:
        alone = {name: (low, high)}
        found.alone[name] = {
            label: safe_rate(spec, n, alone, episodes, seed)
            for spec, label in zip(resolved, labels, strict=True)
        }
        if bar is not None:
            bar.advance(f"n = {n}, {name} alone")
    return found


def _percent(value: float | None) -> str:
    return "-" if value is None else f"{100 * value:.0f}"


def markdown(found: Sequence[CountSweep], episodes: int, seed: int, fresh_seed: int) -> str:
    """One table per n (rows: the ceiling, then the policies; columns: the sizes; cells:
    test / fresh safe %), then the sensitivity (columns: the parameters)."""
    lines = [
        f"{scene_title(ENV_ID)}: safe % against the mismatch size (M, J0, a, l, mu each drawn "
        f"per episode in 1 +- size of nominal), test / fresh starts ({episodes} each, seeds "
        f"{seed}.. and {fresh_seed}..); the ceiling is certified on the test starts "
        "(`python -m agents.certify --randomize mismatch<size>`).",
    ]
    for sweep in found:
        sizes = list(sweep.rates)
        ceilings = []
        for size in sizes:
            opened = sweep.open.get(size)
            ceilings.append(_percent(sweep.ceiling[size]) + (f" ({opened} open)" if opened else ""))
        lines += [
            "",
            f"**n = {sweep.n}**",
            "",
            "| policy | " + " | ".join(f"{size} %" for size in sizes) + " |",
            "|---|" + "---|" * len(sizes),
            "| ceiling | " + " | ".join(ceilings) + " |",
        ]
        # Sorted, as mismatch.json keeps them, so a redraw writes the table measured.
        for label in sorted(sweep.policies):
            cells = [sweep.rates[size][label] for size in sizes]
            lines.append(
                f"| {label} | "
                + " | ".join(f"{_percent(test)} / {_percent(fresh)}" for test, fresh in cells)
                + " |"
            )
    with_alone = [sweep for sweep in found if sweep.alone]
    if with_alone:
        lines += [
            "",
            f"One parameter drawn alone in 1 +- {SENSITIVITY_SIZE} %: safe % on the test "
            "starts (nominal: the 0 % column above); the parameter that costs the policies "
            "that do not read the parameters most, by n:",
            "",
        ]
        for sweep in with_alone:
            names = sorted(sweep.alone)
            lines += [
                f"**n = {sweep.n}**: {sweep.most_costly()}",
                "",
                "| policy | " + " | ".join(names) + " |",
                "|---|" + "---|" * len(names),
            ]
            for label in sorted(sweep.policies):
                alone = [_percent(sweep.alone[name][label]) for name in names]
                lines.append(f"| {label} | " + " | ".join(alone) + " |")
            lines.append("")
    return "\n".join(lines).rstrip("\n") + "\n"


def draw(sweep: CountSweep, out: Path) -> Path:
    """The test rate of every policy and the ceiling against the size, written atomically."""
    from agents.evaluation.plots import PAGE_DPI, PAGE_WIDTH_PX, _pyplot

    plt = _pyplot()
    sizes = list(sweep.rates)
    fig, axis = plt.subplots(figsize=(PAGE_WIDTH_PX / PAGE_DPI / 1.6, 3.4), layout="constrained")
    certified = [size for size in sizes if sweep.ceiling[size] is not None]
    ceiling = [100 * (sweep.ceiling[size] or 0.0) for size in certified]
    axis.plot(certified, ceiling, "k-", lw=2.5, label="ceiling (certified)")
    for label in sweep.policies:
        axis.plot(sizes, [100 * sweep.rates[size][label][0] for size in sizes], "o-", label=label)
    axis.set_title(f"{scene_title(ENV_ID)}, n = {sweep.n}: safe % on the test starts", fontsize=10)
    axis.set_xlabel("mismatch size (% of nominal)")
    axis.set_ylabel("safe %")
    axis.set_xticks(sizes)
    axis.grid(alpha=0.3)
    axis.legend(fontsize=7, loc="lower left")
    with files.replacing(out) as temporary:
        fig.savefig(temporary, dpi=PAGE_DPI)
    plt.close(fig)
    return out


def _sweep_of(n: int, part: object, where: str) -> CountSweep:
    """One n's figures as ``mismatch.json`` holds them (checked whole: ValueError naming
    the file and the entry)."""
    try:
        assert isinstance(part, dict)
        rates = {
            int(size): {label: (float(test), float(fresh)) for label, (test, fresh) in row.items()}
            for size, row in part["safe_rate"].items()
        }
        labels = list(next(iter(rates.values())))
        sweep = CountSweep(n, labels, rates=rates)
        for size in rates:
            ceiling, opened = part["ceiling"][str(size)], part["open"][str(size)]
            sweep.ceiling[size] = None if ceiling is None else float(ceiling)
            sweep.open[size] = None if opened is None else int(opened)
            assert set(rates[size]) == set(labels)
        sweep.alone = {
            str(name): {label: float(row[label]) for label in labels}
            for name, row in part["alone"].items()
        }
    except (AssertionError, KeyError, TypeError, ValueError, StopIteration) as error:
        raise ValueError(f"{where}: n = {n} is not a sweep's figures ({error!r})") from None
    return sweep


def redraw(out: Path) -> str:
    """Write ``mismatch.md`` and the charts again from the measured ``out/mismatch.json``
    (nothing is measured); returns the table.

    Raises:
        ValueError: If the file is not a sweep's document (naming what is wrong).
    """
    where = str(out / "mismatch.json")
    document = files.read_json(out / "mismatch.json")
    try:
        episodes, seed = int(document["episodes"]), int(document["seed"])
        fresh_seed, by_n = int(document["fresh_seed"]), dict(document["by_n"])
    except (KeyError, TypeError, ValueError) as error:
        raise ValueError(f"{where}: not a sweep's document ({error!r})") from None
    found = [_sweep_of(int(n), part, where) for n, part in by_n.items()]
    table = markdown(found, episodes, seed, fresh_seed)
    files.atomic_write_text(out / "mismatch.md", table)
    for sweep in found:
        draw(sweep, out / f"mismatch_n{sweep.n}.png")
    return table


def write_mismatch(
    out: Path,
    counts: Sequence[int],
    specs: Sequence[str],
    sizes: Sequence[int] = SIZES,
    episodes: int = 100,
    seed: int = TEST_SEED,
    fresh_seed: int = FRESH_SEED,
) -> str:
    """Measure every n of ``counts``, write ``mismatch.md``, ``mismatch.json`` and one chart
    per n into ``out`` (atomically) and return the table."""
    phases = len(counts) * (len(sizes) + (len(MISMATCHED) if 0 in sizes else 0))
    with Progress(phases, "mismatch sweep") as bar:
        found = [sweep_count(n, specs, sizes, episodes, seed, fresh_seed, bar) for n in counts]
    table = markdown(found, episodes, seed, fresh_seed)
    document: dict[str, object] = {
        "env_id": ENV_ID,
        "episodes": episodes,
        "seed": seed,
        "fresh_seed": fresh_seed,
        "sizes": list(sizes),
        "sensitivity_size": SENSITIVITY_SIZE,
        "policies": list(specs),
        "by_n": {
            str(sweep.n): {
                "ceiling": {str(size): value for size, value in sweep.ceiling.items()},
                "open": {str(size): value for size, value in sweep.open.items()},
                "safe_rate": {
                    str(size): {label: list(pair) for label, pair in rates.items()}
                    for size, rates in sweep.rates.items()
                },
                "alone": sweep.alone,
                "most_costly": sweep.most_costly() if sweep.alone else None,
            }
            for sweep in found
        },
    }
    out.mkdir(parents=True, exist_ok=True)
    files.atomic_write_text(out / "mismatch.md", table)
    files.write_json(out / "mismatch.json", document)
    for sweep in found:
        draw(sweep, out / f"mismatch_n{sweep.n}.png")
    return table
