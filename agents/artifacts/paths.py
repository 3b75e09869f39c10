"""File names of models, cards, statistics, curves and checkpoints."""

from __future__ import annotations

from pathlib import Path


def model_stem(algo: str, env_id: str, n_trailers: int) -> str:
    """The name of a shipped model: ``ppo_reverse_n2`` for PPO on Reverse-v0 with two trailers."""
    from agents.envs import scene_of

    return f"{algo}_{scene_of(env_id)}_n{n_trailers}"


def card_path(model_path: Path) -> Path:
    """Where the model card of ``model_path`` lives (``x.zip`` -> ``x.json``)."""
    return model_path.with_suffix(".json")


def stats_path(model_path: Path) -> Path:
    """Where the observation-normalisation statistics (JSON) of ``model_path`` live.

    ``x.zip`` -> ``x_vecnormalize.json``; checkpoints ``<algo>_<k>_steps.zip`` ->
    ``<algo>_vecnormalize_<k>_steps.json`` (beside them, as SB3's CheckpointCallback
    names its statistics).
    """
    stem = model_path.stem
    prefix, _, steps = stem.rpartition("_")
    if steps == "steps":
        algo, _, count = prefix.rpartition("_")
        if algo and count.isdigit():
            return model_path.with_name(f"{algo}_vecnormalize_{count}_steps.json")
    return model_path.with_name(f"{stem}_vecnormalize.json")


def pickled_stats_path(model_path: Path) -> Path | None:
    """A legacy pickled ``VecNormalize`` beside ``model_path`` (``.pkl``; rl-zoo3's
    ``<env>/vecnormalize.pkl``), or None."""
    for candidate in (
        stats_path(model_path).with_suffix(".pkl"),
        model_path.with_suffix("") / "vecnormalize.pkl",
    ):
        if candidate.is_file():
            return candidate
    return None


def replay_buffer_path(checkpoint: Path) -> Path | None:
    """The replay buffer CheckpointCallback saved with ``<algo>_<steps>_steps.zip``, if any."""
    stem = checkpoint.stem
    if not stem.endswith("_steps"):
        return None
    prefix = stem.removesuffix("_steps")
    algo, _, steps = prefix.rpartition("_")
    candidate = checkpoint.with_name(f"{algo}_replay_buffer_{steps}_steps.pkl")
    return candidate if candidate.is_file() else None


def curve_path(model_path: Path) -> Path:
    """Where an exported model's learning curve lives (``x.zip`` -> ``x.csv``)."""
    return model_path.with_suffix(".csv")


def export_files(destination: Path) -> list[Path]:
    """The files of a model exported to ``destination``: model, card, statistics, curve
    (:func:`agents.artifacts.run_folder.export_model`)."""
    model = destination.with_suffix(".zip")
    return [model, card_path(model), stats_path(model), curve_path(model)]
