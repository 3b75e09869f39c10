"""The reinforcement-learning-from-reward table: training runs scored on the test protocol
(the program and what it writes: :mod:`agents.commands.rl_from_reward`).

Per run folder of ``agents.train``, its kept model (``best_model.zip``: the best
validation evaluation) and its last model (``final_model.zip``) are scored on the test
episodes and on fresh ones, with the scene's headline rate; the validation curve gives
where the run settled on its final plateau
(:func:`agents.evaluation.learning_curves.final_plateau`) and whether its end still climbs
(:func:`~agents.evaluation.learning_curves.trend`). Runs of one (scene, n, algorithm)
over training seeds are summarised as mean ± sd.
"""

from __future__ import annotations

import re
import statistics
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import ClassVar

from agents.artifacts import files
from agents.artifacts.cards import ModelCard, read_model_card
from agents.artifacts.records import JSONPart, JSONRecord
from agents.artifacts.run_folder import (
    BEST_MODEL,
    CONFIG_FILE,
    CURVE_FILE,
    FINAL_MODEL,
)
from agents.evaluation import selection
from agents.evaluation.learning_curves import (
    TREND_MIN_EVALUATIONS,
    final_plateau,
    read_run,
    rise_text,
    trend,
)
from agents.evaluation.metrics import rollout, summarize
from agents.policies.registry import load_policy
from agents.seeds import TEST_SEED

TABLE = "rl_from_reward.md"
DOCUMENT = "rl_from_reward.json"
#: The folder in ``--out`` keeping the scored runs' curves.
CURVES = "rl_runs"
#: The plateau rule of the table (evaluations, band).
PLATEAU_WINDOW, PLATEAU_EPS = 5, 0.05
TEST_EPISODES = 100


@dataclass(frozen=True)
class RunScore(JSONPart):
    """One run's figures: where it plateaued, and its models on test and fresh seeds."""

    run: str
    env_id: str
    n_trailers: int
    algo: str
    seed: int
    budget: int
    wall_s: float
    metric: str
    plateau_step: float | None
    plateau_level: float | None
    final_validation: float
    best_validation: float
    kept_at: int
    kept_test: float
    kept_fresh: float
    final_test: float
    final_fresh: float
    #: The end's trend (:func:`~agents.evaluation.learning_curves.trend`); None: fewer
    #: evaluations than its window, or a row scored before it and without a kept curve.
    trend_change: float | None = None
    trend_se: float | None = None
    trend_evaluations: int | None = None

    def trend_text(self) -> str:
        """The trend column: "+0.02 ± 0.03", ", rising" when it is; "-" without one."""
        if self.trend_change is None or self.trend_se is None or not self.trend_evaluations:
            return "-"
        return rise_text(self.trend_change, self.trend_se, self.trend_evaluations)


@dataclass(frozen=True)
class RewardTable(JSONRecord):
    """The table's JSON document (``rl_from_reward.json``): every row, and the fresh
    episodes they were scored on."""

    DOCUMENT: ClassVar[str] = "rl_from_reward table"

    fresh_seed: int
    fresh_episodes: int
    runs: tuple[RunScore, ...]


def _rate(model: Path, env_id: str, n: int, seed: int, episodes: int, metric: str) -> float:
    kwargs = {"n_trailers": n}
    policy = load_policy(str(model), env_id, kwargs, seed=seed)
    return float(summarize(rollout(policy, env_id, episodes, seed, kwargs))[metric])


def _identity(score: RunScore) -> tuple[str, int, str, int]:
    """What makes two rows the same run: scene, n, recipe and training seed."""
    return score.env_id, score.n_trailers, score.algo, score.seed


def curve_folder(out: Path, score: RunScore) -> Path:
    """Where the table keeps a run's curve: named by the row's identity."""
    scene = score.env_id.rpartition("/")[2].lower().replace("-", "_")
    recipe = re.sub(r"[^a-z0-9]+", "_", score.algo.lower()).strip("_")
    return out / CURVES / f"{scene}_n{score.n_trailers}_{recipe}_s{score.seed}"


def keep_curve(run_dir: Path, destination: Path) -> None:
    """Copy a run's ``config.json`` and ``evaluations.csv`` to ``destination``, atomically."""
    destination.mkdir(parents=True, exist_ok=True)
    for name in (CONFIG_FILE, CURVE_FILE):
        files.atomic_write_bytes(destination / name, (run_dir / name).read_bytes())


def _kept_at(card: ModelCard) -> int:
    """The step the kept model was selected at (0 is a step: a fine-tuning run whose
    starting model stayed the best), else the card's step count."""
    selected = card.selected_at_timesteps
    return selected if selected is not None else card.timesteps or 0


def score_run(run_dir: Path, fresh_seed: int, fresh_episodes: int) -> RunScore:
    """Score one run folder (see the module docstring)."""
    curve = read_run(run_dir)
    steps, values = curve.series("timesteps")
    walls, _ = curve.series("wall_s")
    flat = final_plateau(steps, values, PLATEAU_WINDOW, PLATEAU_EPS)
    env_id, n, metric = curve.env_id, curve.n_trailers, curve.metric
    if isinstance(n, tuple):
        raise ValueError(
            f"{run_dir} trained one policy for n = {n[0]}-{n[1]}: this table scores one n; "
            "score it on each n with agents.evaluate"
        )
    best, final = run_dir / BEST_MODEL, run_dir / FINAL_MODEL
    card = read_model_card(best)
    end = trend(steps, values)
    return RunScore(
        run=run_dir.name,
        env_id=env_id,
        n_trailers=n,
        algo=curve.algo,
        seed=curve.seed,
        budget=int(steps[-1]),
        wall_s=float(walls[-1]),
        metric=metric,
        plateau_step=None if flat is None else flat.start,
        plateau_level=None if flat is None else flat.level,
        final_validation=float(values[-1]),
        best_validation=float(max(values)),
        kept_at=_kept_at(card),
        kept_test=_rate(best, env_id, n, TEST_SEED, TEST_EPISODES, metric),
        kept_fresh=_rate(best, env_id, n, fresh_seed, fresh_episodes, metric),
        final_test=_rate(final, env_id, n, TEST_SEED, TEST_EPISODES, metric),
        final_fresh=_rate(final, env_id, n, fresh_seed, fresh_episodes, metric),
        trend_change=None if end is None else end.change,
        trend_se=None if end is None else end.se,
        trend_evaluations=None if end is None else end.evaluations,
    )


def export_selected(scores: Sequence[RunScore], folders: Sequence[Path], destination: Path) -> int:
    """Export every run's kept model as a seed sibling and the best on the selection
    episodes as ``destination`` (:func:`agents.evaluation.selection.export_selected`);
    returns the chosen training seed."""
    runs = {score.seed: folder for score, folder in zip(scores, folders, strict=True)}
    chosen, _ = selection.export_selected(runs, destination, scores[0].metric)
    return chosen


def _pct(value: float) -> str:
    return f"{100 * value:.0f}"


def _mean_sd(values: Sequence[float], scale: float = 100.0) -> str:
    mean = statistics.fmean(values) * scale
    sd = statistics.pstdev(values) * scale if len(values) > 1 else 0.0
    return f"{mean:.0f} ± {sd:.0f}"


def markdown(scores: Sequence[RunScore], fresh_seed: int, fresh_episodes: int) -> str:
    """One table per (scene, n): a row per run, then the mean ± sd over its seeds."""
    lines: list[str] = []
    groups: dict[tuple[str, int], list[RunScore]] = {}
    for score in scores:
        groups.setdefault((score.env_id, score.n_trailers), []).append(score)
    for (env_id, n), group in groups.items():
        metric = group[0].metric.removesuffix("_rate")
        lines += [
            f"#### {env_id.split('/')[-1]}, n = {n}",
            "",
            "| run | budget | wall time | plateau from (level) | trend (last third) "
            f"| kept at | {metric} % test kept / final | {metric} % fresh kept / final |",
            "|---|---|---|---|---|---|---|---|",
        ]
        by_algo: dict[str, list[RunScore]] = {}
        for score in sorted(group, key=lambda s: (s.algo, s.seed)):
            by_algo.setdefault(score.algo, []).append(score)
            flat = (
                "not flat at the end"
                if score.plateau_step is None
                else f"{score.plateau_step / 1e6:.1f}M ({score.plateau_level:.2f})"
            )
            lines.append(
                f"| {score.algo} seed {score.seed} | {score.budget / 1e6:.1f}M | "
                f"{score.wall_s / 60:.1f} min | {flat} | {score.trend_text()} | "
                f"{score.kept_at / 1e6:.1f}M | "
                f"{_pct(score.kept_test)} / {_pct(score.final_test)} | "
                f"{_pct(score.kept_fresh)} / {_pct(score.final_fresh)} |"
            )
        for algo, runs in by_algo.items():
            if len(runs) < 2:
                continue
            lines.append(
                f"| **{algo} mean ± sd ({len(runs)} seeds)** | | "
                f"{_mean_sd([r.wall_s for r in runs], 1 / 60)} min | | | | "
                f"{_mean_sd([r.kept_test for r in runs])} / "
                f"{_mean_sd([r.final_test for r in runs])} | "
                f"{_mean_sd([r.kept_fresh for r in runs])} / "
                f"{_mean_sd([r.final_fresh for r in runs])} |"
            )
        lines.append("")
    lines.append(
        f"Test: seeds {TEST_SEED}..{TEST_SEED + TEST_EPISODES - 1}; fresh: seeds "
        f"{fresh_seed}..{fresh_seed + fresh_episodes - 1}. Kept: the run's best validation "
        "evaluation (its --eval-episodes from seed 50,000); final: its last model. Plateau: the "
        f"run's last {PLATEAU_WINDOW} validation evaluations lie within {PLATEAU_EPS} of "
        "their mean (the level); it is reached at the first evaluation from which every "
        "later one stays within that band. Trend: the rise of the least-squares line "
        "through the validation evaluations of the run's last third of steps (at least "
        f"{TREND_MIN_EVALUATIONS}), ± its standard error; rising when over that times "
        "Student's t (97.5 %, the fit's degrees of freedom). Wall time: the run's own clock."
    )
    return "\n".join(lines) + "\n"


def run_folders(paths: Sequence[Path]) -> list[Path]:
    """The finished run folders (``config.json``, best and final model) among ``paths``
    and the folders directly inside them."""
    found = []
    for path in paths:
        if (path / CONFIG_FILE).is_file():
            found.append(path)
        elif path.is_dir():
            found += sorted(p.parent for p in path.glob(f"*/{CONFIG_FILE}"))
    return [p for p in found if (p / BEST_MODEL).is_file() and (p / FINAL_MODEL).is_file()]


def _with_trend(score: RunScore, out: Path) -> RunScore:
    """``score`` with its trend taken from its kept curve in ``out`` (as it was scored
    when there is none)."""
    kept = curve_folder(out, score)
    if not (kept / CURVE_FILE).is_file():
        return score
    end = trend(*read_run(kept).series("timesteps"))
    if end is None:
        return score
    return replace(
        score, trend_change=end.change, trend_se=end.se, trend_evaluations=end.evaluations
    )


def kept_scores(document: Path, fresh_seed: int, fresh_episodes: int) -> list[RunScore]:
    """The rows of an earlier table (``--update``), each with its trend (:func:`_with_trend`).

    Raises:
        ValueError: If it is unreadable or was scored on other fresh episodes.
    """
    try:
        earlier = RewardTable.from_json(files.read_json(document), str(document))
    except (OSError, ValueError) as error:
        raise ValueError(f"cannot read the table {document}: {error}") from None
    scored_on = (earlier.fresh_seed, earlier.fresh_episodes)
    if scored_on != (fresh_seed, fresh_episodes):
        raise ValueError(
            f"{document} was scored on {scored_on[1]} fresh episodes from seed {scored_on[0]}, "
            f"not {fresh_episodes} from {fresh_seed}"
        )
    scores = earlier.runs
    return [_with_trend(score, document.parent) for score in scores]


def merge_scores(kept: Sequence[RunScore], scores: Sequence[RunScore]) -> list[RunScore]:
    """The rows of an updated table: a re-scored run (same scene, n, recipe and seed,
    whatever its folder's name) takes its earlier row's place, so no seed is counted
    twice; new runs come after, in their order."""
    rescored = {_identity(score): score for score in scores}
    merged = [rescored.pop(_identity(score), score) for score in kept]
    return merged + [score for score in scores if _identity(score) in rescored]


def write_table(
    out: Path,
    scores: Sequence[RunScore],
    scored: Sequence[tuple[Path, RunScore]],
    fresh_seed: int,
    fresh_episodes: int,
) -> tuple[Path, Path]:
    """Keep the curve of every ``scored`` (folder, score) in ``out`` (:func:`curve_folder`),
    then write the JSON document and the table of ``scores``, atomically; returns the
    table's and the document's paths."""
    out.mkdir(parents=True, exist_ok=True)
    document = RewardTable(fresh_seed, fresh_episodes, tuple(scores))
    for folder, score in scored:
        keep_curve(folder, curve_folder(out, score))
    files.write_json(out / DOCUMENT, document.to_json())
    files.atomic_write_text(out / TABLE, markdown(scores, fresh_seed, fresh_episodes))
    return out / TABLE, out / DOCUMENT
