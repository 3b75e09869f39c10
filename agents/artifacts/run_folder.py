"""The run folder of a training: its default name, what it holds, and when it may be reused.

A run folder (default ``runs/<scene>_n<n>_<algo>_s<seed>``) holds a run once it has
its ``config.json`` or ``evaluations.csv``. A fresh training refuses such a folder
unless told to overwrite it (then the files of the earlier run are removed first); a
resumed training goes on in its checkpoint's own run folder.

Nothing a run writes follows a symbolic link: a folder whose run files (config.json,
evaluations.csv, the models, ``checkpoints/`` and what is in it, ``logs/``) include a
link is refused (:func:`symlink_problem`), fresh, resumed or overwritten. While a run
writes its folder it holds ``<run>/.lock`` (:class:`agents.artifacts.files.RunLock`).

A run that is resumed is checked whole before anything is written: its record
(:func:`read_run_record`) must match the resumed run's in every setting that shapes it
(:func:`record_differences`), and every file the resume reads back must be readable
(:func:`resume_problem`); a refusal names the file, or the setting with its old and new
value, and leaves the folder as it was.
"""

from __future__ import annotations

import contextlib
import dataclasses
import shutil
from collections.abc import Iterator, Sequence
from pathlib import Path

from agents.artifacts import files
from agents.artifacts.cards import (
    RECORD_KEYS,
    ModelCard,
    read_model_card,
    recipe_command,
    write_card,
)
from agents.artifacts.curves import CURVE_COLUMNS, read_curve
from agents.artifacts.files import write_json
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
#: An imitation run's checkpoint and data set (:mod:`agents.training.imitate`).
IMITATION_CHECKPOINT = "checkpoint.json"
IMITATION_DATASET = "dataset.npz"
#: Files of an earlier run that a fresh start in its folder removes (with ``--overwrite``):
#: everything a resume reads back, so that a fresh run cut short is never resumed from
#: the earlier run's checkpoint, data or models.
STALE_FILES = (
    CURVE_FILE,
    CONFIG_FILE,
    PROGRESS_FILE,
    BEST_MODEL,
    card_path(Path(BEST_MODEL)).name,
    stats_path(Path(BEST_MODEL)).name,
    stats_path(Path(BEST_MODEL)).with_suffix(".pkl").name,
    FINAL_MODEL,
    card_path(Path(FINAL_MODEL)).name,
    stats_path(Path(FINAL_MODEL)).name,
    IMITATION_CHECKPOINT,
    IMITATION_DATASET,
)
#: Folders of an earlier run removed likewise.
STALE_FOLDERS = (CHECKPOINTS, RLLIB_CHECKPOINT)
#: Everything else a run writes in its folder (checked for links with the above).
RUN_FILES = ("logs", "ray_logs", files.LOCK_FILE)


class RunFolderError(ValueError):
    """The run folder cannot be used as asked (not a folder, or it holds another run)."""


def default_run_dir(env_id: str, algo: str, n_trailers: int | tuple[int, int], seed: int) -> Path:
    """``runs/<scene>_n<n>_<algo>_s<seed>`` (a range: ``n<low>-<high>``)."""
    label = "-".join(map(str, n_trailers)) if isinstance(n_trailers, tuple) else n_trailers
    return Path("runs") / f"{scene_of(env_id)}_n{label}_{algo}_s{seed}"


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
    folder = checkpoint_folder(checkpoint)
    return folder if (folder / CONFIG_FILE).is_file() else None


def checkpoint_folder(checkpoint: Path) -> Path:
    """The folder whose run a checkpoint would belong to (resolved): the one holding it,
    or the one above its ``checkpoints/``."""
    parent = checkpoint.resolve().parent
    return parent.parent if parent.name == CHECKPOINTS else parent


def symlink_problem(folder: Path) -> str | None:
    """The first symbolic link among the files a run writes in ``folder`` (None: none)."""
    names = (*STALE_FILES, *STALE_FOLDERS, *RUN_FILES)
    candidates = [folder / name for name in names]
    for sub in (CHECKPOINTS, "logs", RLLIB_CHECKPOINT):
        inside = folder / sub
        if inside.is_dir() and not inside.is_symlink():
            candidates += sorted(inside.rglob("*"))
    for path in candidates:
        if path.is_symlink():
            return f"{path} is a symbolic link; a run never writes through links"
    return None


def choose_run_dir(
    default: Path,
    run_dir: Path | None = None,
    resume: Path | None = None,
    overwrite: bool = False,
    *,
    clear: bool = True,
) -> Path:
    """The run folder: ``run_dir``, else the resumed checkpoint's run, else ``default``.

    A fresh start (or a resume into a folder that is not the checkpoint's run) in a
    folder that already holds a run removes that run's files when ``overwrite`` (and
    ``clear``: without it nothing is removed, the folder is only checked).

    Raises:
        RunFolderError: If the folder is a file or not writable, holds another run and
            ``overwrite`` is false, or a run file in it is a symbolic link.
    """
    own_run = run_dir_of_checkpoint(resume) if resume is not None else None
    chosen = run_dir or own_run or default
    problem = files.writable_problem(chosen, folder=True) or symlink_problem(chosen)
    if problem is not None:
        raise RunFolderError(problem)
    continuing = own_run is not None and chosen.resolve() == own_run
    if not continuing and holds_run(chosen):
        if not overwrite:
            raise RunFolderError(
                f"{chosen} already holds a run; pass --resume <checkpoint>, another "
                "--run-dir, or --overwrite"
            )
        if clear:
            clear_run(chosen, everything=False)
    return chosen


def clear_run(folder: Path, everything: bool = True) -> None:
    """Remove an earlier run's files from ``folder``: :data:`STALE_FILES` and
    :data:`STALE_FOLDERS` (``everything``: the other run files too, but the lock);
    nothing else in the folder is touched."""
    names = (*STALE_FILES, *STALE_FOLDERS, *(RUN_FILES if everything else ()))
    for name in names:
        path = folder / name
        if name == files.LOCK_FILE or not (path.exists() or path.is_symlink()):
            continue
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()


def write_config(run_dir: Path, record: ModelCard) -> Path:
    """Write the run's ``config.json`` that :func:`read_run_record` reads.

    Raises:
        TypeError: If ``record`` is not a :class:`~agents.artifacts.cards.ModelCard`.
    """
    if not isinstance(record, ModelCard):
        raise TypeError(f"write_config takes a ModelCard, got {type(record).__name__}")
    return write_json(run_dir / CONFIG_FILE, record.to_json())


def read_run_record(run_dir: Path) -> ModelCard:
    """The run's record (its ``config.json``), read bounded and checked: a JSON object with
    :data:`RECORD_KEYS`, read by :class:`~agents.artifacts.cards.ModelCard`.

    Raises:
        ValueError: Naming the file and what is wrong: missing, unreadable, not JSON, not
            a JSON object, a key missing, unknown or of another type.
    """
    path = run_dir / CONFIG_FILE
    if not path.is_file():
        raise ValueError(f"{path} is missing")
    record = files.read_json(path, "run record")
    if not isinstance(record, dict):
        raise ValueError(f"run record {path} is not a JSON object")
    missing = [key for key in RECORD_KEYS if key not in record]
    if missing:
        raise ValueError(f"run record {path} lacks {', '.join(map(repr, missing))}")
    try:
        return ModelCard.from_json(record, str(path))
    except ValueError as error:
        raise ValueError(str(error).replace("model card", "run record", 1)) from None


def comparable_hyperparams(value: object) -> object:
    """A recorded ``hyperparams`` setting as the hyperparameter files give it: SB3's
    off-policy algorithms write ``use_sde: False`` (their default) into the
    ``policy_kwargs`` they are given, so older records carry it and the files do not."""
    if isinstance(value, dict):
        kwargs = value.get("policy_kwargs")
        if isinstance(kwargs, dict) and kwargs.get("use_sde") is False:
            trimmed = {key: item for key, item in kwargs.items() if key != "use_sde"}
            value = {**value, "policy_kwargs": trimmed}
    return value


def record_differences(
    saved: ModelCard, wanted: ModelCard, free: tuple[str, ...] = ()
) -> list[tuple[str, object, object]]:
    """The settings whose values differ between a run's ``saved`` record and the record
    of its continuation ``wanted`` (as JSON), as ``(key, old, new)``; a nested setting as
    ``a.b``; a setting at its default (absent from the JSON) has the value None. Keys in
    ``free`` (either ``a`` or ``a.b``) may differ.
    """
    hyperparams = "hyperparams"  # compared as the hyperparameter files give them
    kept, asked = saved.to_json(), wanted.to_json()
    for document in (kept, asked):
        document[hyperparams] = comparable_hyperparams(document.get(hyperparams))
    differing: list[tuple[str, object, object]] = []
    for key in sorted(set(kept) | set(asked)):
        if key in free:
            continue
        old, new = kept.get(key), asked.get(key)
        if isinstance(old, dict) and isinstance(new, dict):
            differing += [
                (f"{key}.{sub}", old.get(sub), new.get(sub))
                for sub in sorted(set(old) | set(new), key=str)
                if old.get(sub) != new.get(sub) and f"{key}.{sub}" not in free
            ]
        elif old != new:
            differing.append((key, old, new))
    return differing


def resume_problem(run_dir: Path) -> str | None:
    """Why an SB3 training run in ``run_dir`` could not go on (None: it can), found
    without writing: its learning curve (:data:`CURVE_FILE`, the resumed run keeps its
    rows and appends under its header) or its best model's card (the resumed run reads
    when that model was selected) is unreadable."""
    try:
        read_curve(run_dir / CURVE_FILE, CURVE_COLUMNS, header=CURVE_COLUMNS)
        read_model_card(run_dir / BEST_MODEL)
    except ValueError as error:
        return str(error)
    return None


def export_problem(destination: Path, overwrite: bool = False) -> str | None:
    """Why the run's model could not be exported to ``destination`` (None: it could),
    found without writing: a file there without ``overwrite``, a link, no writable folder."""
    try:
        targets = export_files(destination)
    except ValueError:  # "", ".", "..": no file name
        return f"{str(destination)!r} names no file (give e.g. models/name.zip)"
    for path in targets:
        problem = files.writable_problem(path)
        if problem is not None:
            return problem
        if path.exists() and not overwrite:
            return f"{path} exists; pass --overwrite to replace it"
    return None


#: The models a run folder offers to ``export_model``, by the name ``--export-model`` takes.
EXPORTABLE_MODELS = {"best": BEST_MODEL, "final": FINAL_MODEL}


def kept_model(arguments: Sequence[str]) -> str:
    """The file of a run folder that a training command's ``arguments`` keep as the run's
    result: ``final_model.zip`` after ``--export-model final``, else ``best_model.zip``."""
    arguments = list(arguments)
    if "--export-model" in arguments[:-1]:
        return EXPORTABLE_MODELS.get(arguments[arguments.index("--export-model") + 1], BEST_MODEL)
    return BEST_MODEL


def export_model(
    run_dir: Path, destination: Path, overwrite: bool = False, model: str = "best"
) -> Path:
    """Copy the run's ``model`` (``best``: the best by validation, the default; ``final``:
    the model at the end of the budget), its card, statistics and learning curve to
    ``destination`` (each file atomically; the model last, so that it appears with its
    sidecars). The exported card's command is the recipe alone
    (:func:`~agents.artifacts.cards.recipe_command`): where the run's files went is not
    part of it.

    Raises:
        ValueError: If ``model`` is not one of :data:`EXPORTABLE_MODELS`.
        FileNotFoundError: If the run has no such model.
        FileExistsError: If one of the destination files exists and ``overwrite`` is false.
        UnsafeFileError: If one of them is a symbolic link.
    """
    if model not in EXPORTABLE_MODELS:
        raise ValueError(f"model must be one of {sorted(EXPORTABLE_MODELS)}, got {model!r}")
    source = run_dir / EXPORTABLE_MODELS[model]
    if not source.is_file():
        raise FileNotFoundError(f"{run_dir} has no {source.name} to export")
    existing = [path for path in export_files(destination) if path.exists()]
    if existing and not overwrite:
        raise FileExistsError(f"{existing[0]} exists; pass --overwrite to replace it")
    for path in export_files(destination):
        files.refuse_symlink(path)
    destination = destination.with_suffix(".zip")
    destination.parent.mkdir(parents=True, exist_ok=True)
    if card_path(source).is_file():
        card = read_model_card(source)
        write_card(destination, dataclasses.replace(card, command=recipe_command(card.command)))
    if stats_path(source).is_file():
        files.atomic_write_bytes(stats_path(destination), stats_path(source).read_bytes())
    curve = run_dir / CURVE_FILE
    if curve.is_file():
        files.atomic_write_bytes(curve_path(destination), curve.read_bytes())
    files.atomic_write_bytes(destination, source.read_bytes())
    return destination


def with_curve_validation(card: ModelCard, curve: Path) -> ModelCard:
    """``card``, with the learning curve's row at its last step as its validation where it
    has none (the final model's card: it was evaluated there, not kept there)."""
    if card.validation is not None or card.timesteps is None:
        return card
    rows = [row for row in read_curve(curve) if int(row["timesteps"]) == card.timesteps]
    if not rows:
        return card
    row = {key: (int(value) if key == "timesteps" else value) for key, value in rows[-1].items()}
    return ModelCard.from_json({**card.to_json(), "validation": row}, str(curve))


@contextlib.contextmanager
def claimed_run_dir(
    default: Path,
    run_dir: Path | None = None,
    resume: Path | None = None,
    overwrite: bool = False,
) -> Iterator[Path]:
    """The run folder (:func:`choose_run_dir`), locked for the block and cleared of an
    earlier run (with ``overwrite``) only once the lock is held.

    A folder this created and that is left holding nothing (the block failed before
    writing) is removed again.

    Raises:
        RunFolderError: As :func:`choose_run_dir`, or when another live process holds
            the folder's lock.
    """
    chosen = choose_run_dir(default, run_dir, resume, overwrite, clear=False)
    existed = chosen.exists()
    lock = files.RunLock(chosen)
    try:
        lock.acquire()
    except files.FolderLockedError as error:
        raise RunFolderError(str(error)) from None
    try:
        chosen = choose_run_dir(default, run_dir, resume, overwrite)
        yield chosen
    finally:
        lock.release()
        if not existed:
            with contextlib.suppress(OSError):
                chosen.rmdir()  # only if empty: a refused run leaves nothing
