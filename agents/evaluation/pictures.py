"""The pictures of an evaluation: margin histograms, frames, learning curves."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from agents.artifacts.paths import curve_path
from agents.envs import MakeKwargs, env_settings
from agents.evaluation.results import Evaluation, curve_metric
from agents.policies.registry import is_model_spec, load_policy


def learning_curve(evaluation: Evaluation) -> Path | None:
    """The learning curve (``evaluations.csv`` exported as ``<model>.csv``) of a model, if any."""
    if not is_model_spec(evaluation.spec):
        return None
    curve = curve_path(Path(evaluation.spec))
    return curve if curve.is_file() else None


def baseline_levels(evaluations: Sequence[Evaluation], metric: str) -> dict[str, float]:
    """The baselines' ``metric``, drawn as levels over the learning curves.

    The random baseline is left out: it marks no level a trained agent is measured
    against (zero and the controllers do).
    """
    return {
        e.label: e.summary.rate(metric)
        for e in evaluations
        if not is_model_spec(e.spec) and e.label != "random"
    }


def write_pictures(
    evaluations: Sequence[Evaluation],
    env_id: str,
    env_kwargs: MakeKwargs,
    out: Path,
    seed: int,
    prefix: str = "",
) -> list[Path]:
    """Margin histograms, rendered frames and (if any) learning curves under ``out``."""
    from agents.evaluation import plots

    settings = env_settings(env_kwargs)
    n = settings.n_trailers
    title = f"{env_id}, n = {n}, {evaluations[0].results.returns.size} episodes"
    written = [
        plots.plot_margin_histograms(
            {e.label: e.results for e in evaluations},
            settings.singular_band,
            out / f"{prefix}margins.png",
            title,
        )
    ]
    rows = {}
    for evaluation in evaluations:
        if evaluation.label == "random":
            continue
        # A model is stateless and reused; a baseline is built afresh, since some keep
        # state across calls (the random generator, a replay's step count).
        policy = evaluation.policy if is_model_spec(evaluation.spec) else None
        policy = policy or load_policy(evaluation.spec, env_id, env_kwargs, seed=seed)
        rows[evaluation.label] = plots.render_frames(env_id, policy, seed, dict(env_kwargs))
    if rows:
        frames_title = (
            f"{env_id}, n = {n}, episode seed {seed}\ngreen: outside the singular band, red: in it"
        )
        written.append(plots.plot_frames(rows, out / f"{prefix}frames.png", frames_title))
    curves = {e.label: curve for e in evaluations if (curve := learning_curve(e)) is not None}
    if curves:
        metric = curve_metric(env_id)
        title = f"{env_id}, n = {n}: validation episodes during training"
        written.append(
            plots.plot_learning_curves(
                curves,
                out / f"{prefix}curves.png",
                baseline_levels(evaluations, metric),
                title,
                metric,
            )
        )
    return written
