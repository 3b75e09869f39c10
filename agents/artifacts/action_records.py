"""Action-record archives: a certificate's feasible starts' records in one ``.npz``.

One float64 array ``seed_<seed>`` per start, one action per step, every action in
[-1, 1]; written and read without pickles (``allow_pickle=False``), and read back only
if it holds nothing else.
"""

from __future__ import annotations

import zipfile
import zlib
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from agents.artifacts import files

#: Largest action record accepted (steps x action dimensions): Reverse's 400 steps.
_MAX_RECORD = 100_000


def write_actions(actions: Mapping[int, np.ndarray], path: Path) -> Path:
    """Write the action records of a certificate as one ``.npz`` (no pickles)."""
    arrays = {
        f"seed_{seed}": np.asarray(sequence, dtype=np.float64) for seed, sequence in actions.items()
    }
    with files.replacing(path) as temporary:
        np.savez_compressed(temporary, **arrays)  # type: ignore[arg-type]
    return path


def read_actions(path: Path) -> dict[int, np.ndarray]:
    """The action records of an archive that :func:`write_actions` wrote (seed -> (T, d)
    float64 actions in [-1, 1]), read with ``allow_pickle=False``.

    Raises:
        ValueError: If the file is missing or holds anything but finite records in
            [-1, 1] named ``seed_<int>``.
    """
    records: dict[int, np.ndarray] = {}
    try:
        with np.load(path, allow_pickle=False) as archive:
            for key in archive.files:
                prefix, _, digits = key.partition("_")
                if prefix != "seed" or not digits.isdigit():
                    raise _RecordError(f"{path}: unexpected entry {key!r:.60}")
                info = archive.zip.getinfo(f"{key}.npy")
                if info.file_size > 8 * _MAX_RECORD + 1024:
                    raise _RecordError(f"{path}: entry {key!r} is larger than any episode")
                record = np.asarray(archive[key])
                if record.dtype != np.float64 or record.ndim not in (1, 2):
                    raise _RecordError(f"{path}: entry {key!r} is not a float64 action record")
                if not np.all(np.isfinite(record)) or np.any(np.abs(record) > 1.0):
                    raise _RecordError(f"{path}: entry {key!r} holds actions outside [-1, 1]")
                records[int(digits)] = record.reshape(len(record), -1)
    except _RecordError:
        raise
    except (OSError, KeyError, EOFError, ValueError, zipfile.BadZipFile, zlib.error) as error:
        # A cut or damaged archive fails inside numpy or zipfile in many ways (no central
        # directory, a bad CRC, a cut deflate stream, a header numpy cannot parse).
        reason = str(error).splitlines()[0][:120] if str(error) else type(error).__name__
        raise ValueError(
            f"{path} is not an action-record archive (cut or damaged?): {reason}"
        ) from None
    return records


class _RecordError(ValueError):
    """A readable archive whose content is not a certificate's action records."""


__all__ = ["read_actions", "write_actions"]
