"""Which training seed becomes the committed model (the program:
:mod:`agents.commands.select`).

Each training seed's kept model plays the selection episodes (200 from
:data:`agents.seeds.SELECTION_SEED`, which no table uses) in the env its card records: its
number of trailers, its physics (a model trained under ``randomize="mismatch20"`` is
chosen under mismatch20) and its memory window; one policy for a range of counts plays
them at each count of its range, its rate the mean over the counts. The seed with the
best headline rate of the scene (safe on Reverse, success on the goal scenes) is
committed, ties to the lower seed, and its card records every seed's rate
(:class:`~agents.artifacts.cards.Selection`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

from agents.artifacts.cards import Selection, read_model_card, write_card
from agents.artifacts.run_folder import BEST_MODEL, export_model
from agents.artifacts.shipped import SEEDS_DIR
from agents.envs import headline_metric
from agents.evaluation.metrics import rollout, summarize
from agents.policies.registry import load_policy
from agents.seeds import SELECTION_SEED

SELECTION_EPISODES = 200


def card_env(model: Path) -> tuple[str, dict[str, object]]:
    """The scene and env keywords ``model``'s card records (its n or range of n, physics
    and window).

    Raises:
        ValueError: If the card names no scene.
    """
    card = read_model_card(model)
    if card.env_id is None:
        raise ValueError(f"{model}: its card names no scene")
    return card.env_id, card.env_kwargs.as_kwargs()


def env_key(env_id: str, kwargs: Mapping[str, object]) -> tuple[object, ...]:
    """What runs of one recipe share (:func:`card_env`'s scene and keywords), hashable."""
    return (env_id, *sorted((key, str(value)) for key, value in kwargs.items()))


def counts_of(kwargs: Mapping[str, object]) -> list[int]:
    """The counts a card's env keywords cover: its one n, or each n of its range."""
    n = kwargs["n_trailers"]
    if isinstance(n, (list, tuple)):
        low, high = n
        return list(range(int(low), int(high) + 1))
    return [int(n)]  # type: ignore[call-overload]


def selection_rate(model: Path, metric: str | None = None) -> float:
    """``model``'s headline rate (or ``metric``) on the selection episodes, in its card's
    env; for one policy over a range of counts, the mean of its rates at each count."""
    env_id, kwargs = card_env(model)
    metric = metric or headline_metric(env_id)
    rates = []
    for n in counts_of(kwargs):
        at_n = {**kwargs, "n_trailers": n}
        policy = load_policy(str(model), env_id, at_n, seed=SELECTION_SEED)
        played = rollout(policy, env_id, SELECTION_EPISODES, SELECTION_SEED, at_n)
        rates.append(float(summarize(played)[metric]))
    return sum(rates) / len(rates)


def export_selected(
    runs: Mapping[int, Path], destination: Path, metric: str | None = None
) -> tuple[int, dict[int, float]]:
    """Export each run's kept model as ``<destination's folder>/seeds/<stem>_s<seed>.zip``
    and the best on the selection episodes as ``destination`` (``runs``: training seed to
    run folder, all of one scene, n, physics and window); returns the chosen seed and
    every seed's rate. Existing files are replaced (the caller asks first)."""
    envs = {seed: card_env(folder / BEST_MODEL) for seed, folder in runs.items()}
    if len({env_key(*env) for env in envs.values()}) != 1:
        raise ValueError("the runs' cards record different scenes, n, physics or windows")
    env_id = next(iter(envs.values()))[0]
    metric = metric or headline_metric(env_id)
    rates = {seed: selection_rate(folder / BEST_MODEL, metric) for seed, folder in runs.items()}
    chosen = max(sorted(rates), key=lambda seed: rates[seed])
    by_seed = {str(seed): rate for seed, rate in sorted(rates.items())}
    selection = Selection(
        chosen_seed=chosen,
        seeds=(SELECTION_SEED, SELECTION_SEED + SELECTION_EPISODES - 1),
        safe_rate_per_training_seed=by_seed if metric == "safe_rate" else None,
        success_rate_per_training_seed=None if metric == "safe_rate" else by_seed,
    )
    seeds_dir = destination.parent / SEEDS_DIR.name
    for seed, folder in sorted(runs.items()):
        _export(folder, seeds_dir / f"{destination.stem}_s{seed}.zip", None)
    _export(runs[chosen], destination, selection)
    return chosen, rates


def _export(run_dir: Path, destination: Path, selection: Selection | None) -> None:
    """Export ``run_dir``'s kept model to ``destination`` (:func:`export_model`: its card's
    command the recipe alone), its card recording ``selection`` when given."""
    path = export_model(run_dir, destination, True)
    if selection is not None:
        write_card(path, replace(read_model_card(path), selection=selection))
