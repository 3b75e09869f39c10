"""A DAgger run's checkpoint: written after every iteration, read back whole before a
resume writes anything (:func:`read_saved_run`), and restored into the run
(:func:`restore`) so that it ends as an uninterrupted run would."""

from __future__ import annotations

import io
import json
import pickle
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from agents.artifacts import files, limits
from agents.artifacts.cards import ModelCard, read_model_card
from agents.artifacts.curves import CURVE_COLUMNS, read_curve
from agents.artifacts.files import atomic_write_bytes
from agents.artifacts.paths import card_path, stats_path
from agents.artifacts.records import DocumentError, JSONRecord
from agents.artifacts.run_folder import (
    BEST_MODEL,
    CONFIG_FILE,
    CURVE_FILE,
    FINAL_MODEL,
    IMITATION_CHECKPOINT,
    IMITATION_DATASET,
    read_run_record,
    record_differences,
)
from agents.artifacts.sb3_zip import check_zip, save_model
from agents.artifacts.stats import read_stats, restore_stats, save_stats
from agents.oracles.labellers import Labeller
from agents.training.imitation_config import ImitationConfig

if TYPE_CHECKING:
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

#: Keys of the run's record that the best model's card takes at the end of the run.
RUN_TOTALS = ("timesteps", "wall_time_s", "simulated_steps")

#: The aggregated data set (observations: normalised, or raw with "trailers"; labels) in the
#: run folder.
DATASET_FILE = IMITATION_DATASET

#: The run's checkpoint, rewritten after every iteration (with the data set and the final
#: model): what ``--resume`` continues from.
CHECKPOINT_FILE = IMITATION_CHECKPOINT

#: Columns of the run's evaluations.csv: one row per iteration.
CURVE_FIELDS = (*CURVE_COLUMNS, "iteration", "loss")
#: The column of the iteration's number.
ITERATION = CURVE_FIELDS[-2]

#: Keys of the run's record that may differ when a run is resumed (the rest must match):
#: the command, the budget and the iterations asked for, the totals of the run so far and
#: the host's speed (measured again at each start).
RESUMABLE_KEYS = (
    "command",
    "budget",
    "imitation.iterations",
    "resumed_at",
    "host",
    *RUN_TOTALS,
)


def _rng_problem(state: object) -> str | None:
    """Why ``state`` is not the state of a generator of the run (None: it is one)."""
    try:
        np.random.default_rng().bit_generator.state = state  # type: ignore[assignment]
    except (TypeError, ValueError, KeyError, OverflowError) as error:
        return f"{type(error).__name__}: {error}"
    return None


@dataclass(frozen=True)
class Checkpoint(JSONRecord):
    """``checkpoint.json``: what a DAgger run has done, written after every iteration.

    Attributes:
        iterations: Iterations done (>= 1).
        rows: Rows of the data set (>= 1).
        best: The best validation score so far (:func:`agents.training.callbacks.score`).
        wall_s: Wall time so far (>= 0).
        simulated_steps: The expert's simulated steps so far (>= 0).
        fit_rng: The regression's generator state.
        expert_rngs: The expert's generators' states, in its order.
    """

    DOCUMENT: ClassVar[str] = CHECKPOINT_FILE

    iterations: int
    rows: int
    best: tuple[float, float, float]
    wall_s: float
    simulated_steps: int
    fit_rng: object
    expert_rngs: tuple[object, ...]

    def __post_init__(self) -> None:
        for name, least in (("iterations", 1), ("rows", 1), ("simulated_steps", 0)):
            if getattr(self, name) < least:
                raise DocumentError(
                    f"{name!r} must be an integer >= {least}, got {getattr(self, name)}"
                )
        if not all(map(files.is_number, self.best)):
            raise DocumentError(f"'best' must be 3 finite numbers (a score), got {self.best}")
        if not (files.is_number(self.wall_s) and self.wall_s >= 0):
            raise DocumentError(f"'wall_s' must be a finite number >= 0, got {self.wall_s}")
        problem = _rng_problem(self.fit_rng)
        if problem is not None:
            raise DocumentError(f"'fit_rng' is not a generator's state ({problem:.80})")
        for index, state in enumerate(self.expert_rngs):
            problem = _rng_problem(state)
            if problem is not None:
                raise DocumentError(
                    f"'expert_rngs'[{index}] is not a generator's state ({problem:.80})"
                )


class CheckpointError(ValueError):
    """A run cannot be resumed: no checkpoint, a damaged one, or another configuration."""


@dataclass
class RunState:
    """What a DAgger run has done so far (restored from its checkpoint on resume)."""

    iterations: int = 0
    data_obs: list[np.ndarray] | None = None
    data_labels: list[np.ndarray] | None = None
    curve: list[dict[str, float]] | None = None
    best: tuple[float, ...] | None = None
    wall_s: float = 0.0
    simulated_steps: int = 0


@dataclass(frozen=True)
class SavedRun:
    """The files of an imitation run that its resume reads back, read and checked
    (:func:`read_saved_run`)."""

    checkpoint: Checkpoint
    record: ModelCard
    observations: np.ndarray
    labels: np.ndarray
    curve: list[dict[str, float]]


def _refused(run_dir: Path, name: str, problem: str) -> CheckpointError:
    return CheckpointError(f"cannot resume {run_dir}: {name}: {problem}")


def _read_dataset(run_dir: Path, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """The data set's observations and labels, checked against the checkpoint's ``rows``.

    Raises:
        CheckpointError: Naming the file and what is wrong.
    """
    path = run_dir / DATASET_FILE
    members = {"observations.npy", "labels.npy"}
    try:
        with zipfile.ZipFile(path) as archive:
            infos = archive.infolist()
        if {info.filename for info in infos} != members:
            raise ValueError(f"its members are not {sorted(members)}")
        size = sum(info.file_size for info in infos)
        if size > limits.MAX_ZIP_TOTAL_BYTES:
            raise ValueError(f"it inflates to {size} bytes, over {limits.MAX_ZIP_TOTAL_BYTES}")
        with np.load(path, allow_pickle=False) as dataset:
            observations, labels = (dataset[name] for name in ("observations", "labels"))
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as error:
        raise _refused(run_dir, path.name, f"unreadable ({error})") from None
    if observations.dtype != np.float32 or observations.ndim != 2:
        shown = f"{observations.dtype} {observations.shape}"
        raise _refused(run_dir, path.name, f"observations are {shown}, not 2-D float32")
    if labels.dtype != np.float64 or labels.shape != (len(labels), 1):
        shown = f"{labels.dtype} {labels.shape}"
        raise _refused(run_dir, path.name, f"labels are {shown}, not float64 (rows, 1)")
    if len(observations) != len(labels) or len(labels) != rows:
        raise _refused(
            run_dir,
            path.name,
            f"holds {len(observations)} observations and {len(labels)} labels, the "
            f"checkpoint {rows}; a run was cut while writing it",
        )
    if not (np.all(np.isfinite(observations)) and np.all(np.isfinite(labels))):
        raise _refused(run_dir, path.name, "holds values that are not finite")
    return observations, labels


def read_saved_run(run_dir: Path) -> SavedRun:
    """Every file a resume of the imitation run in ``run_dir`` reads back, read and
    checked, before anything is written: :data:`CHECKPOINT_FILE` (its counts, best score,
    times and random streams), the record (``config.json``), the data set (its arrays,
    as many rows as the checkpoint says), the learning curve (one row per iteration done,
    under the run's header), the final model (a bounded zip) and its statistics (a
    normalising student), and the best model's card (and that model).

    Raises:
        CheckpointError: Naming the file and what is wrong with it.
    """
    path = run_dir / CHECKPOINT_FILE
    if not path.is_file():
        raise _refused(run_dir, path.name, "missing")
    try:
        checkpoint = Checkpoint.from_json(files.read_json(path, "checkpoint"))
    except DocumentError as error:
        raise CheckpointError(f"cannot resume {run_dir}: {error}") from None
    except ValueError as error:
        raise _refused(run_dir, path.name, str(error)) from None
    try:
        record = read_run_record(run_dir)
    except ValueError as error:
        raise _refused(run_dir, CONFIG_FILE, str(error)) from None
    done = checkpoint.iterations
    observations, labels = _read_dataset(run_dir, checkpoint.rows)
    try:
        curve = read_curve(run_dir / CURVE_FILE, CURVE_FIELDS, header=CURVE_FIELDS)
    except ValueError as error:
        raise _refused(run_dir, CURVE_FILE, str(error)) from None
    if [int(row[ITERATION]) for row in curve] != list(range(done)):
        raise _refused(
            run_dir,
            CURVE_FILE,
            f"holds {len(curve)} iterations, the checkpoint {done}; a run was cut while writing it",
        )
    for model in (run_dir / FINAL_MODEL, run_dir / BEST_MODEL):
        if not model.is_file():  # the best: the checkpoint has a best score
            raise _refused(run_dir, model.name, "missing")
        try:
            check_zip(model)
        except ValueError as error:
            raise _refused(run_dir, model.name, str(error)) from None
    try:
        read_model_card(run_dir / BEST_MODEL)  # the card the run's end completes
    except ValueError as error:
        raise _refused(run_dir, card_path(run_dir / BEST_MODEL).name, str(error)) from None
    final_stats = stats_path(run_dir / FINAL_MODEL)
    if record.normalize is not None:
        if not final_stats.is_file():
            raise _refused(run_dir, final_stats.name, "missing")
        try:
            read_stats(final_stats)
        except ValueError as error:
            raise _refused(run_dir, final_stats.name, str(error)) from None
    return SavedRun(checkpoint, record, observations, labels, curve)


def restore(
    run_dir: Path,
    config: ImitationConfig,
    record: ModelCard,
    model: PPO,
    stats: VecNormalize | None,
    planner: Labeller,
    rng: np.random.Generator,
    width: int,
) -> tuple[RunState, ModelCard]:
    """Load the run's checkpoint into the model, statistics and random streams; returns
    what the run has done and its saved record. ``width``: the numbers of the labelling
    env's observation (what the data set holds). Nothing is written.

    Raises:
        CheckpointError: If a file of the run is missing or damaged
            (:func:`read_saved_run`), the run was configured differently from ``record``
            (other than :data:`RESUMABLE_KEYS`; the message gives each setting's old and
            new value), it has already done ``config.iterations``, or its model,
            statistics or random streams do not fit the run's.
    """
    saved = read_saved_run(run_dir)
    differing = record_differences(saved.record, record, RESUMABLE_KEYS)
    if differing:
        shown = ", ".join(f"{key} = {old!r:.40}, not {new!r:.40}" for key, old, new in differing)
        raise _refused(run_dir, CONFIG_FILE, f"its run was configured differently ({shown})")
    checkpoint = saved.checkpoint
    done = checkpoint.iterations
    if done >= config.iterations:
        raise CheckpointError(
            f"cannot resume {run_dir}: it has done {done} iterations; ask for more "
            f"(--iterations > {done})"
        )
    if saved.observations.shape[1] != width:
        raise _refused(
            run_dir,
            DATASET_FILE,
            f"observations of {saved.observations.shape[1]} numbers, the run's have {width}",
        )
    final = run_dir / FINAL_MODEL
    try:
        model.set_parameters(str(final), exact_match=True, device="cpu")
        if stats is not None:
            restore_stats(stats, read_stats(stats_path(final)))
    except (
        OSError,
        ValueError,
        KeyError,
        RuntimeError,
        EOFError,
        zipfile.BadZipFile,
        pickle.UnpicklingError,  # torch's weights-only loader refuses the entry
    ) as error:
        first = (str(error).splitlines() or [""])[0]
        problem = f"does not load into the run's student ({first:.200})"
        raise _refused(run_dir, final.name, problem) from None
    rng.bit_generator.state = checkpoint.fit_rng  # type: ignore[assignment]
    streams = planner.random_streams()
    if len(streams) != len(checkpoint.expert_rngs):
        raise _refused(run_dir, CHECKPOINT_FILE, "the expert's random streams differ")
    for stream, state in zip(streams, checkpoint.expert_rngs, strict=True):
        stream.bit_generator.state = state  # type: ignore[assignment]
    state = RunState(
        iterations=done,
        data_obs=[saved.observations],
        data_labels=[saved.labels],
        curve=saved.curve,
        best=checkpoint.best,
        wall_s=checkpoint.wall_s,
        simulated_steps=checkpoint.simulated_steps,
    )
    return state, saved.record


def write_checkpoint(
    run_dir: Path,
    progress: RunState,
    model: PPO,
    stats: VecNormalize | None,
    planner: Labeller,
    rng: np.random.Generator,
) -> None:
    """The data set, the model and statistics as they are, then the checkpoint naming them
    (written last: a run cut while writing leaves a checkpoint that :func:`restore` refuses)."""
    observations = np.concatenate(progress.data_obs or [])
    labels = np.concatenate(progress.data_labels or [])
    dataset = io.BytesIO()
    np.savez_compressed(dataset, observations=observations, labels=labels)
    atomic_write_bytes(run_dir / DATASET_FILE, dataset.getvalue())
    if stats is not None:
        save_stats(stats, stats_path(run_dir / FINAL_MODEL))
    save_model(model, run_dir / FINAL_MODEL)
    best = progress.best or (0.0, 0.0, 0.0)
    checkpoint = Checkpoint(
        iterations=progress.iterations,
        rows=len(labels),
        best=(best[0], best[1], best[2]),
        wall_s=progress.wall_s,
        simulated_steps=progress.simulated_steps,
        fit_rng=rng.bit_generator.state,
        expert_rngs=tuple(stream.bit_generator.state for stream in planner.random_streams()),
    )
    text = json.dumps(checkpoint.to_json(), indent=1)
    atomic_write_bytes(run_dir / CHECKPOINT_FILE, text.encode())
