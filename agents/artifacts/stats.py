"""Observation-normalisation statistics as JSON; the legacy pickled format (trusted files only)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from agents.artifacts import files
from agents.artifacts.records import DocumentError, JSONPart, JSONRecord, finite

if TYPE_CHECKING:
    from stable_baselines3.common.running_mean_std import RunningMeanStd

#: Format tag of the statistics files (their version).
STATS_FORMAT = "trailer_env-vecnormalize/1"
#: The key that holds it.
FORMAT_KEY = "format"


#: The settings a statistics file holds beside its running statistics.
SETTINGS = ("norm_obs", "norm_reward", "clip_obs", "clip_reward", "gamma", "epsilon")
#: The longest observation a statistics file may describe.
MAX_STATS_SIZE = 100_000


@dataclasses.dataclass(frozen=True)
class RunningStats(JSONPart):
    """A running mean and variance (SB3's ``RunningMeanStd``): vectors, or numbers for
    the return's."""

    mean: tuple[float, ...] | float
    var: tuple[float, ...] | float
    count: float

    def __post_init__(self) -> None:
        for name in ("mean", "var"):
            values = np.atleast_1d(np.asarray(getattr(self, name), dtype=np.float64))
            if not 0 < values.size <= MAX_STATS_SIZE:
                raise DocumentError(
                    f"{name!r} must be a non-empty list of at most {MAX_STATS_SIZE} numbers"
                )
            if not np.all(np.isfinite(values)):
                raise DocumentError(f"{name!r} holds non-finite values")
        if np.shape(self.mean) != np.shape(self.var):
            raise DocumentError("'mean' and 'var' must be of one length")
        if np.any(np.asarray(self.var) < 0):
            raise DocumentError("'var' holds negative-variance values")
        if not (finite(self.count) and self.count >= 0):
            raise DocumentError(f"'count' must be a finite number >= 0, got {self.count}")

    def running_mean_std(self) -> RunningMeanStd:
        """SB3's ``RunningMeanStd`` holding these statistics (float64, exact)."""
        from stable_baselines3.common.running_mean_std import RunningMeanStd

        rms = RunningMeanStd(shape=np.shape(self.mean))
        rms.mean = np.asarray(self.mean, dtype=np.float64)
        rms.var = np.asarray(self.var, dtype=np.float64)
        rms.count = self.count
        return rms

    @classmethod
    def of(cls, rms: RunningMeanStd) -> RunningStats:
        """The statistics of SB3's ``RunningMeanStd`` ``rms``."""

        def values(array: object) -> tuple[float, ...] | float:
            listed = np.asarray(array, dtype=np.float64).tolist()
            return tuple(listed) if isinstance(listed, list) else float(listed)

        return cls(values(rms.mean), values(rms.var), float(rms.count))


@dataclasses.dataclass(frozen=True)
class NormalizationStats(JSONRecord):
    """A statistics file: a ``VecNormalize``'s settings and running statistics. Its
    version is :data:`STATS_FORMAT` (``format``)."""

    DOCUMENT: ClassVar[str] = "statistics file"
    VERSIONED: ClassVar[bool] = False

    format: str
    norm_obs: bool
    norm_reward: bool
    clip_obs: float
    clip_reward: float
    gamma: float
    epsilon: float
    obs_rms: RunningStats
    ret_rms: RunningStats

    def __post_init__(self) -> None:
        if self.format != STATS_FORMAT:
            raise DocumentError(f"'format' must be {STATS_FORMAT!r}, got {self.format!r:.60}")
        for name in ("clip_obs", "clip_reward", "gamma", "epsilon"):
            if not finite(getattr(self, name)):
                raise DocumentError(f"{name!r} must be a finite number")
        if not isinstance(self.obs_rms.mean, tuple):
            raise DocumentError("'obs_rms' needs a list of means (one per observation entry)")

    @property
    def observation_shape(self) -> tuple[int, ...]:
        """The shape of the observations these statistics normalise."""
        return tuple(np.shape(self.obs_rms.mean))


def stats_document(vecnormalize: Any) -> NormalizationStats:
    """A ``VecNormalize``'s statistics and settings (float64, exact)."""
    return NormalizationStats(
        format=STATS_FORMAT,
        norm_obs=bool(vecnormalize.norm_obs),
        norm_reward=bool(vecnormalize.norm_reward),
        clip_obs=float(vecnormalize.clip_obs),
        clip_reward=float(vecnormalize.clip_reward),
        gamma=float(vecnormalize.gamma),
        epsilon=float(vecnormalize.epsilon),
        obs_rms=RunningStats.of(vecnormalize.obs_rms),
        ret_rms=RunningStats.of(vecnormalize.ret_rms),
    )


def save_stats(vecnormalize: object, path: Path) -> Path:
    """Write a ``VecNormalize``'s statistics as JSON (Python's float repr round-trips exactly)."""
    document = stats_document(vecnormalize).to_json()
    return files.atomic_write_text(path, json.dumps(document, indent=1) + "\n")


def check_stats(document: object, where: str) -> NormalizationStats:
    """The statistics ``document`` (parsed JSON) holds.

    Raises:
        ValueError: Naming ``where`` and what is missing or wrong.
    """
    if not isinstance(document, dict) or document.get(FORMAT_KEY) != STATS_FORMAT:
        raise ValueError(f"{where} is not a {STATS_FORMAT} statistics file")
    return NormalizationStats.from_json(document, where)


def read_stats(path: Path) -> NormalizationStats:
    """Read and check a statistics file written by :func:`save_stats`.

    Raises:
        ValueError: If it is not such a file (size, format, fields, types, finite numbers).
    """
    try:
        document = files.read_json(path, "the file")
    except ValueError as error:
        raise ValueError(f"{path} is not a statistics JSON file: {error}") from None
    return check_stats(document, str(path))


def restore_stats(vecnormalize: Any, document: NormalizationStats) -> Any:
    """Put saved statistics and settings into a ``VecNormalize`` (returns it).

    Raises:
        ValueError: If the saved observation statistics do not fit its observations.
    """
    obs_rms = document.obs_rms.running_mean_std()
    expected = tuple(vecnormalize.observation_space.shape)
    if obs_rms.mean.shape != expected:
        raise ValueError(
            f"statistics for observations of shape {obs_rms.mean.shape}, "
            f"but the environment gives {expected}"
        )
    vecnormalize.obs_rms = obs_rms
    vecnormalize.ret_rms = document.ret_rms.running_mean_std()
    for name in SETTINGS:
        setattr(vecnormalize, name, getattr(document, name))
    return vecnormalize


def frozen_normalizer(document: NormalizationStats, observation_space: object) -> Any:
    """A read-only ``VecNormalize`` without an env, for ``normalize_obs`` at evaluation.

    It is built the way SB3's own unpickling builds one (``__setstate__``, no venv), so
    the normalisation is SB3's code, not a copy of its formula.
    """
    from stable_baselines3.common.vec_env import VecNormalize

    normalizer = VecNormalize.__new__(VecNormalize)
    normalizer.__setstate__(
        {
            "observation_space": observation_space,
            "norm_obs_keys": None,
            "training": False,
            "returns": np.zeros(1),
        }
    )
    restore_stats(normalizer, document)
    return normalizer


def convert_pickled_stats(pickled: Path, destination: Path, overwrite: bool = False) -> Path:
    """Convert a legacy pickled ``VecNormalize`` (``*_vecnormalize.pkl``) to the JSON format.

    This unpickles ``pickled``: run it only on files you trust (your own runs).
    Command line: ``python -m agents.model_files --trust-pickle OLD.pkl NEW.json``.

    Raises:
        FileExistsError: If ``destination`` exists and ``overwrite`` is false.
    """
    if destination.exists() and not overwrite:
        raise FileExistsError(f"{destination} exists; pass --overwrite to replace it")
    return save_stats(load_pickled_stats(pickled), destination)


def load_pickled_stats(pickled: Path) -> Any:
    """Unpickle a legacy ``VecNormalize`` (read-only, no env). Only for trusted files."""
    import pickle

    with pickled.open("rb") as handle:
        vecnormalize = pickle.load(handle)  # the caller vouches for the file
    vecnormalize.training = False
    return vecnormalize
