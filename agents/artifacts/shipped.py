"""The models shipped in the package, their training-seed siblings, and stems resolved to paths."""

from __future__ import annotations

import re
from pathlib import Path

from agents.artifacts.cards import read_model_card

#: Where shipped models live (inside the installed package, not the working directory).
MODELS_DIR = Path(__file__).resolve().parent.parent / "models"


def resolve_model(spec: str) -> str:
    """A shipped model's path from its stem (``ppo_reverse_n2`` ->
    ``<package>/models/ppo_reverse_n2.zip``; a training seed's sibling in ``seeds/`` and a
    teacher in ``teachers/`` by theirs); other specs (paths, baseline names) are returned
    unchanged."""
    if "/" in spec or Path(spec).suffix:
        return spec
    for folder in (MODELS_DIR, SEEDS_DIR, TEACHERS_DIR):
        shipped = folder / f"{spec}.zip"
        if shipped.is_file():
            return str(shipped)
    return spec


def shipped_models() -> list[str]:
    """Stems of the models shipped in :data:`MODELS_DIR`."""
    return sorted(path.stem for path in MODELS_DIR.glob("*.zip"))


#: The models of every training seed of the committed models (see :func:`seed_models`).
SEEDS_DIR = MODELS_DIR / "seeds"

#: The privileged teachers (they read the convoy's parameters) the students that adapt
#: learned from: committed so that those students' recipes run from committed files.
TEACHERS_DIR = MODELS_DIR / "teachers"


def committed_models(
    env_id: str, n_trailers: int, directory: Path = MODELS_DIR, randomize: object = None
) -> list[Path]:
    """Models under ``directory`` whose card names ``env_id``, ``n_trailers`` and the
    physics ``randomize`` (None: nominal; a model trained under randomised physics is not
    the nominal scenario's policy, nor the other way round)."""
    found = []
    for path in sorted(directory.glob("*.zip")):
        card = read_model_card(path)
        if (
            card.env_id == env_id
            and card.n_trailers == n_trailers
            and card.env_kwargs.randomize == randomize
        ):
            found.append(path)
    return found


def models_covering(env_id: str, n_trailers: int, directory: Path = MODELS_DIR) -> list[Path]:
    """Models under ``directory`` trained on ``env_id`` with nominal physics that take
    ``n_trailers``: those of that count (:func:`committed_models`), then those trained over
    a range of counts that holds it (``n_trailers: [low, high]`` on the card). A model
    trained under randomised physics is left out: it is not that scenario's policy."""
    found = committed_models(env_id, n_trailers, directory)
    for path in sorted(directory.glob("*.zip")):
        card = read_model_card(path)
        counts = card.n_trailers
        if (
            card.env_id == env_id
            and isinstance(counts, tuple)
            and counts[0] <= n_trailers <= counts[1]
            and card.env_kwargs.randomize is None
        ):
            found.append(path)
    return found


def seed_models(spec: str, directory: Path = SEEDS_DIR) -> list[Path]:
    """The models of every training seed of a committed model: ``<seeds>/<stem>_s<k>.zip``.

    A committed model is the best of its configuration's training seeds; the others (and
    a copy of it) are kept under ``agents/models/seeds/`` so that tables can report the
    spread over seeds. Only a model in the folder above ``directory`` has siblings (a
    model of the same name from anywhere else is not the committed one). Empty for
    baselines and for models without siblings.
    """
    path = Path(resolve_model(spec))
    if path.is_dir() or path.resolve().parent != directory.resolve().parent:
        return []
    pattern = re.compile(re.escape(path.stem) + r"_s\d+")
    return sorted(
        candidate
        for candidate in directory.glob(f"{path.stem}_s*.zip")
        if pattern.fullmatch(candidate.stem)
    )
