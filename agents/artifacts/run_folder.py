"""The run folder of a training: its default name, what it holds, and when it may be reused.

A run folder (default ``runs/<scene>_n<n>_<algo>_s<seed>``) holds a run once it has
its ``config.json`` or ``evaluations.csv``. A fresh training refuses such a folder
unless told to overwrite it (then the files of the earlier run are removed first); a
resumed training goes on in its checkpoint's own run folder.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

from agents.artifacts.cards import write_json
from agents.artifacts.paths import card_path, curve_path, export_files, stats_path
from agents.envs import scene_of

#: The run's record (:meth:`agents.training.config.TrainConfig.document`).
CONFIG_FILE = "config.json"
#: The learning curve (:class:`agents.training.callbacks.SafetyEvalCallback`).
CURVE_FILE = "evaluations.csv"
#: RLlib's per-iteration statistics (:mod:`agents.training.rllib`).
PROGRESS_FILE = "progress.csv"
#: The best model so far (by validation) and the model at the end of the budget.
BEST_MODEL = "best_model.zip"
FINAL_MODEL = "final_model.zip"
#: SB3's periodic checkpoints; RLlib's checkpoint.
CHECKPOINTS = "checkpoints"
RLLIB_CHECKPOINT = "checkpoint"
#: Files of an earlier run that a fresh start in its folder removes (with ``--overwrite``).
STALE_FILES = (
    CURVE_FILE,
    CONFIG_FILE,
    PROGRESS_FILE,
    BEST_MODEL,
    card_path(Path(BEST_MODEL)).name,
    stats_path(Path(BEST_MODEL)).name,
    stats_path(Path(BEST_MODEL)).with_suffix(".pkl").name,
)
#: Folders of an earlier run removed likewise.
STALE_FOLDERS = (CHECKPOINTS, RLLIB_CHECKPOINT)


class RunFolderError(ValueError):
    """The run folder cannot be used as asked (not a folder, or it holds another run)."""


def default_run_dir(env_id: str, algo: str, n_trailers: int, seed: int) -> Path:
    """``runs/<scene>_n<n>_<algo>_s<seed>``."""
    return Path("runs") / f"{scene_of(env_id)}_n{n_trailers}_{algo}_s{seed}"


def holds_run(folder: Path) -> bool:
    """Whether ``folder`` already holds a run (its record or its learning curve)."""
    return (folder / CURVE_FILE).exists() or (folder / CONFIG_FILE).exists()


def run_dir_of_checkpoint(checkpoint: Path) -> Path | None:
    """The run folder a checkpoint belongs to, or None when it is in none.

    A checkpoint belongs to a run when it lies in the run's folder or in its
    ``checkpoints/`` subfolder and that folder holds the run's ``config.json``.
    Anything else (a shipped model in ``agents/models/``, a downloaded file) is not
    in a run: resuming it starts a fresh run folder, it never turns the file's folder
    into one.
    """
    parent = checkpoint.resolve().parent
    folder = parent.parent if parent.name == CHECKPOINTS else parent
    return folder if (folder / CONFIG_FILE).is_file() else None


def choose_run_dir(
    default: Path, run_dir: Path | None = None, resume: Path | None = None, overwrite: bool = False
) -> Path:
    """The run folder: ``run_dir``, else the resumed checkpoint's run, else ``default``.

    A fresh start (or a resume into a folder that is not the checkpoint's run) in a
    folder that already holds a run removes that run's files when ``overwrite``.

    Raises:
        RunFolderError: If the folder is a file, or holds another run and ``overwrite``
            is false.
    """
    own_run = run_dir_of_checkpoint(resume) if resume is not None else None
    chosen = run_dir or own_run or default
    if chosen.exists() and not chosen.is_dir():
        raise RunFolderError(f"{chosen} exists and is not a folder")
    continuing = own_run is not None and chosen.resolve() == own_run
    if not continuing and holds_run(chosen):
        if not overwrite:
            raise RunFolderError(
                f"{chosen} already holds a run; pass --resume <checkpoint>, another "
                "--run-dir, or --overwrite"
            )
        for stale in STALE_FILES:
            (chosen / stale).unlink(missing_ok=True)
        for folder in STALE_FOLDERS:
            shutil.rmtree(chosen / folder, ignore_errors=True)
    return chosen


def write_config(run_dir: Path, record: dict[str, Any]) -> Path:
    """Write the run's ``config.json``."""
    return write_json(run_dir / CONFIG_FILE, record)


def export_model(run_dir: Path, destination: Path, overwrite: bool = False) -> Path:
    """Copy the run's best model, its card, statistics and learning curve to ``destination``.

    Raises:
        FileNotFoundError: If the run has no best model.
        FileExistsError: If one of the destination files exists and ``overwrite`` is false.
    """
    source = run_dir / BEST_MODEL
    if not source.is_file():
        raise FileNotFoundError(f"{run_dir} has no {BEST_MODEL} to export")
    existing = [path for path in export_files(destination) if path.exists()]
    if existing and not overwrite:
        raise FileExistsError(f"{existing[0]} exists; pass --overwrite to replace it")
    destination = destination.with_suffix(".zip")
    destination.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(source, destination)
    for sidecar in (card_path, stats_path):
        if sidecar(source).is_file():
            shutil.copyfile(sidecar(source), sidecar(destination))
    curve = run_dir / CURVE_FILE
    if curve.is_file():
        shutil.copyfile(curve, curve_path(destination))
    return destination
