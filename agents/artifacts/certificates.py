"""Certificate files: names, statuses, the committed ones, writing."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np

#: Committed certificates: ``certificate.json`` of the commands in docs/physics.md
#: section 14 (the per-start statuses; the action records are rebuilt by the command).
CERTIFICATES_DIR = Path(__file__).resolve().parent.parent / "certificates"


FEASIBLE = "feasible"


NOT_RECOVERABLE = "not recoverable"


OPEN = "open"


def write_certificate(certificate: dict[str, Any], out: Path, overwrite: bool) -> None:
    """Write certificate.json, certificate.md and actions/seed_<seed>.npy under ``out``.

    Raises:
        FileExistsError: If ``out`` exists and ``overwrite`` is False.
    """
    if out.exists():
        if not overwrite:
            raise FileExistsError(f"{out} exists; pass --overwrite to replace it")
        shutil.rmtree(out)
    (out / "actions").mkdir(parents=True)
    document = {key: value for key, value in certificate.items() if key != "actions"}
    for start in document["starts"]:
        if start["status"] == FEASIBLE:
            start["actions_file"] = f"actions/seed_{start['seed']}.npy"
    (out / "certificate.json").write_text(json.dumps(document, indent=2) + "\n")
    (out / "certificate.md").write_text(markdown(certificate))
    for seed, sequence in certificate["actions"].items():
        np.save(out / "actions" / f"seed_{seed}.npy", sequence, allow_pickle=False)


def certificate_path(env_id: str, n_trailers: int, directory: Path = CERTIFICATES_DIR) -> Path:
    """Where the committed certificate of a scene and n lives: ``<scene>_n<n>.json``."""
    from agents.envs import scene_of

    return directory / f"{scene_of(env_id)}_n{n_trailers}.json"


def committed_certificate(
    env_id: str, n_trailers: int, directory: Path = CERTIFICATES_DIR
) -> dict[str, Any] | None:
    """The committed certificate of ``env_id`` with ``n_trailers``, or None.

    Raises:
        ValueError: If the file is not a certificate of that scene and n.
    """
    path = certificate_path(env_id, n_trailers, directory)
    if not path.is_file():
        return None
    try:
        document = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ValueError(f"{path} is not JSON: {error}") from None
    if (
        not isinstance(document, dict)
        or document.get("env_id") != env_id
        or document.get("env_kwargs", {}).get("n_trailers") != n_trailers
        or not isinstance(document.get("starts"), list)
    ):
        raise ValueError(f"{path} is not a certificate of {env_id} with n = {n_trailers}")
    return document


def markdown(certificate: dict[str, Any]) -> str:
    """The certificate's summary and per-start table in Markdown."""
    count = certificate["episodes"]
    lines = [
        f"# {certificate['env_id']}, n = {certificate['env_kwargs']['n_trailers']}, "
        f"seeds {certificate['seeds'][0]}-{certificate['seeds'][1]}",
        "",
        f"ceiling (feasible, replayed): {certificate['feasible']}/{count} = "
        f"{100 * certificate['ceiling']:.0f}%; not recoverable (screen): "
        f"{certificate['not_recoverable']}; open: {certificate['open']}",
        f"planner: {certificate['planner']['first_pass_safe']}/{count} safe in one pass "
        f"({certificate['planner']['first_pass_wall_time_s']} s), "
        f"{certificate['planner']['wall_time_s']} s with up to "
        f"{certificate['planner']['restarts']} restarts; "
        f"screen: {certificate['screen']['wall_time_s']} s",
        "",
        "| seed | status | screen stroke / s_max | planner steps |",
        "|---|---|---|---|",
    ]
    for start in certificate["starts"]:
        fraction = start["screen_stroke_fraction"]
        stroke = "inf" if fraction is None else f"{fraction:.2f}"
        lines.append(
            f"| {start['seed']} | {start['status']} | {stroke} | {start['planner_length']} |"
        )
    return "\n".join(lines) + "\n"


#: Largest action record accepted (steps x action dimensions): Reverse's 400 steps.
_MAX_RECORD = 100_000


def actions_path(env_id: str, n_trailers: int, directory: Path = CERTIFICATES_DIR) -> Path:
    """Where the committed action records of a certificate live: ``<scene>_n<n>_actions.npz``
    (one float64 array ``seed_<seed>`` per feasible start, one action per step)."""
    path = certificate_path(env_id, n_trailers, directory)
    return path.with_name(path.stem + "_actions.npz")


def write_actions(actions: dict[int, np.ndarray], path: Path) -> Path:
    """Write the action records of a certificate as one ``.npz`` (no pickles)."""
    arrays = {
        f"seed_{seed}": np.asarray(sequence, dtype=np.float64)
        for seed, sequence in actions.items()
    }
    temporary = path.with_name(f".{path.name}.tmp.npz")
    np.savez_compressed(temporary, **arrays)  # type: ignore[arg-type]
    temporary.replace(path)
    return path


def committed_actions(
    env_id: str, n_trailers: int, directory: Path = CERTIFICATES_DIR
) -> dict[int, np.ndarray] | None:
    """The committed action records of ``env_id`` with ``n_trailers`` (seed -> (T, d)
    float64 actions in [-1, 1]), or None when none are committed.

    Read with ``allow_pickle=False``: the file holds numbers only.

    Raises:
        ValueError: If the file holds anything but finite records in [-1, 1] named
            ``seed_<int>``.
    """
    path = actions_path(env_id, n_trailers, directory)
    if not path.is_file():
        return None
    records: dict[int, np.ndarray] = {}
    try:
        with np.load(path, allow_pickle=False) as archive:
            for key in archive.files:
                prefix, _, digits = key.partition("_")
                if prefix != "seed" or not digits.isdigit():
                    raise ValueError(f"{path}: unexpected entry {key!r}")
                info = archive.zip.getinfo(f"{key}.npy")
                if info.file_size > 8 * _MAX_RECORD + 1024:
                    raise ValueError(f"{path}: entry {key!r} is larger than any episode")
                record = np.asarray(archive[key])
                if record.dtype != np.float64 or record.ndim not in (1, 2):
                    raise ValueError(f"{path}: entry {key!r} is not a float64 action record")
                if not np.all(np.isfinite(record)) or np.any(np.abs(record) > 1.0):
                    raise ValueError(f"{path}: entry {key!r} holds actions outside [-1, 1]")
                records[int(digits)] = record.reshape(len(record), -1)
    except (OSError, KeyError) as error:
        raise ValueError(f"{path} is not an action-record archive: {error}") from None
    return records
