"""Certificate files: names, statuses, the committed ones, writing and checking them.

A certificate is read back only if it is one (:func:`check_certificate`): its
counts are integers that add up, ``ceiling`` is a finite number in [0, 1], every
start has an integer seed and a known status (:data:`STATUSES`), and the stroke
fractions are finite or null. Writing it (``--overwrite`` included) replaces only
the files the command writes (:data:`CERTIFICATE_JSON`, :data:`CERTIFICATE_MD`,
``actions/seed_<seed>.npy``), each atomically; any other file in the folder stays
(an existing folder is written into only with ``overwrite``).
"""

from __future__ import annotations

import io
import json
import math
import re
import zipfile
import zlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from agents.artifacts import files
from trailer_env.json_types import JSONObject

#: Committed certificates: ``certificate.json`` of the commands in docs/physics.md
#: section 14 (the per-start statuses; the action records are rebuilt by the command).
CERTIFICATES_DIR = Path(__file__).resolve().parent.parent / "certificates"


FEASIBLE = "feasible"


NOT_RECOVERABLE = "not recoverable"


OPEN = "open"


#: Every status a start may have.
STATUSES = (FEASIBLE, NOT_RECOVERABLE, OPEN)
#: The files of a certificate folder.
CERTIFICATE_JSON = "certificate.json"
CERTIFICATE_MD = "certificate.md"
ACTIONS = "actions"
#: Every record in one archive: the file to commit as ``<scene>_n<n>_actions.npz``.
ACTIONS_ARCHIVE = "actions.npz"
_ACTION_FILE = re.compile(r"seed_-?\d+\.npy")


def own_files(out: Path) -> list[Path]:
    """The files of a certificate in ``out`` that writing one replaces (those that exist
    among certificate.json, certificate.md, actions.npz, actions/ and
    actions/seed_<seed>.npy)."""
    found = [out / CERTIFICATE_JSON, out / CERTIFICATE_MD, out / ACTIONS_ARCHIVE, out / ACTIONS]
    actions = out / ACTIONS
    if actions.is_dir() and not actions.is_symlink():
        found += sorted(path for path in actions.iterdir() if _ACTION_FILE.fullmatch(path.name))
    return [path for path in found if path.exists() or path.is_symlink()]


def write_problem(out: Path, overwrite: bool) -> str | None:
    """Why a certificate could not be written to ``out`` (None if it could), without writing."""
    problem = files.writable_problem(out, folder=True)
    if problem is not None:
        return problem
    if out.exists() and not overwrite:
        return f"{out} exists; pass --overwrite to replace it"
    existing = own_files(out) if out.is_dir() else []
    for path in existing:
        if path.is_symlink():
            return f"{path} is a symbolic link; refusing to write through it"
    actions = out / ACTIONS
    if actions.exists() and not actions.is_dir():
        return f"{actions} exists and is not a folder"
    return None


def write_certificate(certificate: JSONObject, out: Path, overwrite: bool) -> None:
    """Write certificate.json, certificate.md, actions/seed_<seed>.npy and actions.npz (the
    same records in one archive, the file that is committed beside a certificate as
    ``<scene>_n<n>_actions.npz``) under ``out``.

    Only those files are replaced (``actions/seed_*.npy`` of an earlier certificate
    included); nothing else in ``out`` is touched. certificate.json is written last.

    Raises:
        FileExistsError: If ``out`` exists and ``overwrite`` is False.
        UnsafeFileError: If one of the files to write is a symbolic link.
    """
    problem = write_problem(out, overwrite)
    if problem is not None:
        if "exists; pass --overwrite" in problem:
            raise FileExistsError(problem)
        raise files.UnsafeFileError(problem)
    (out / ACTIONS).mkdir(parents=True, exist_ok=True)
    document = {key: value for key, value in certificate.items() if key != "actions"}
    for start in document["starts"]:
        if start["status"] == FEASIBLE:
            start["actions_file"] = f"{ACTIONS}/seed_{start['seed']}.npy"
    keep = {f"seed_{seed}.npy" for seed in certificate["actions"]}
    for path in own_files(out):
        if path.parent.name == ACTIONS and path.name not in keep:
            path.unlink()
    for seed, sequence in certificate["actions"].items():
        buffer = io.BytesIO()
        np.save(buffer, np.asarray(sequence), allow_pickle=False)
        files.atomic_write_bytes(out / ACTIONS / f"seed_{seed}.npy", buffer.getvalue())
    write_actions(certificate["actions"], out / ACTIONS_ARCHIVE)
    files.atomic_write_text(out / CERTIFICATE_MD, markdown(certificate))
    files.atomic_write_text(out / CERTIFICATE_JSON, json.dumps(document, indent=2) + "\n")


def planner_name(certificate: Mapping[str, object]) -> str:
    """The planner that made a certificate: ``planner.name`` (``ilqr``), else ``mpc`` (the
    sampling planner's certificates were written before planners had names)."""
    planner = certificate.get("planner")
    name = planner.get("name") if isinstance(planner, dict) else None
    return name if isinstance(name, str) else "mpc"


def start_source(certificate: Mapping[str, object], start: Mapping[str, object]) -> str | None:
    """Who found a start's record: its ``source`` (a witness's label, or the planner's
    name), the planner's name for a feasible start of a certificate written before
    sources were kept, None for a start that is not feasible."""
    if start.get("status") != FEASIBLE:
        return None
    source = start.get("source")
    return source if isinstance(source, str) else planner_name(certificate)


def check_certificate(document: object, where: str) -> JSONObject:
    """``document`` if it is a certificate (schema, finite numbers, known statuses).

    Raises:
        ValueError: Naming ``where`` and the first thing that is wrong.
    """

    def fail(what: str) -> ValueError:
        return ValueError(f"{where} is not a valid certificate: {what}")

    if not isinstance(document, dict):
        raise fail("not a JSON object")
    if not isinstance(document.get("env_id"), str):
        raise fail("env_id must be a string")
    kwargs = document.get("env_kwargs")
    if not isinstance(kwargs, dict) or not files.is_integer(kwargs.get("n_trailers"), 0):
        raise fail("env_kwargs.n_trailers must be an integer >= 0")
    starts = document.get("starts")
    if not isinstance(starts, list) or not starts:
        raise fail("starts must be a non-empty list")
    seeds = document.get("seeds")
    if not isinstance(seeds, list) or len(seeds) != 2 or not all(map(files.is_integer, seeds)):
        raise fail("seeds must be [first, last], two integers")
    counts = {status: 0 for status in STATUSES}
    seen = set()
    for index, start in enumerate(starts):
        if not isinstance(start, dict):
            raise fail(f"starts[{index}] is not an object")
        seed, status = start.get("seed"), start.get("status")
        if not files.is_integer(seed) or seed in seen:
            raise fail(f"starts[{index}].seed must be an integer, once")
        seen.add(seed)
        if status not in STATUSES:
            raise fail(f"starts[{index}].status {status!r:.40} is none of {list(STATUSES)}")
        counts[status] += 1
        fraction = start.get("screen_stroke_fraction")
        if fraction is not None and not files.is_number(fraction):
            raise fail(f"starts[{index}].screen_stroke_fraction must be a finite number or null")
        if "planner_length" in start and not files.is_integer(start["planner_length"], 0):
            raise fail(f"starts[{index}].planner_length must be an integer >= 0")
        source = start.get("source")
        if source is not None and (not isinstance(source, str) or status != FEASIBLE):
            raise fail(f"starts[{index}].source must be a string, and only on a feasible start")
    if document.get("episodes") != len(starts):
        raise fail(f"episodes must be the number of starts ({len(starts)})")
    for key, status in (
        ("feasible", FEASIBLE),
        ("not_recoverable", NOT_RECOVERABLE),
        ("open", OPEN),
    ):
        if not files.is_integer(document.get(key), 0) or document[key] != counts[status]:
            raise fail(f"{key} must be the number of {status!r} starts ({counts[status]})")
    sources = document.get("sources")
    if sources is not None:
        found: dict[str, int] = {}
        for start in starts:
            source = start_source(document, start)
            if source is not None:
                found[source] = found.get(source, 0) + 1
        if sources != found:
            raise fail(f"sources must count the feasible starts by source ({found})")
    ceiling: Any = document.get("ceiling")
    if not files.is_number(ceiling) or not math.isclose(
        float(ceiling), counts[FEASIBLE] / len(starts), abs_tol=1e-9
    ):
        raise fail("ceiling must be the feasible fraction of the starts")
    return document


def read_certificate(path: Path) -> JSONObject:
    """A certificate file, checked (:func:`check_certificate`).

    Raises:
        ValueError: If it is too large, not JSON, or not a valid certificate.
    """
    return check_certificate(files.read_json(path, "certificate"), str(path))


def certificate_path(
    env_id: str,
    n_trailers: int,
    directory: Path = CERTIFICATES_DIR,
    randomize: str | None = None,
) -> Path:
    """Where the committed certificate of a scene and n lives: ``<scene>_n<n>.json``, or
    under the randomisation preset ``randomize`` ``<scene>_<preset>_n<n>.json``."""
    from agents.envs import scene_of

    physics = "" if randomize is None else f"_{randomize}"
    return directory / f"{scene_of(env_id)}{physics}_n{n_trailers}.json"


def committed_certificate(
    env_id: str,
    n_trailers: int,
    directory: Path = CERTIFICATES_DIR,
    randomize: str | None = None,
) -> JSONObject | None:
    """The committed certificate of ``env_id`` with ``n_trailers`` (and the randomisation
    preset ``randomize``; None: nominal physics), or None.

    Raises:
        ValueError: If the file is not a certificate of that scene, n and randomisation.
    """
    path = certificate_path(env_id, n_trailers, directory, randomize)
    if not path.is_file():
        return None
    document = read_certificate(path)
    kwargs = document["env_kwargs"]
    if (
        document["env_id"] != env_id
        or kwargs["n_trailers"] != n_trailers
        or kwargs.get("randomize") != randomize
    ):
        physics = "nominal physics" if randomize is None else f"randomize={randomize}"
        raise ValueError(
            f"{path} is not a certificate of {env_id} with n = {n_trailers} and {physics}"
        )
    return document


def markdown(certificate: JSONObject) -> str:
    """The certificate's summary and per-start table in Markdown."""
    count = certificate["episodes"]
    lines = [
        f"# {certificate['env_id']}, n = {certificate['env_kwargs']['n_trailers']}, "
        f"seeds {certificate['seeds'][0]}-{certificate['seeds'][1]}" + _physics_title(certificate),
        "",
        *_physics_lines(certificate),
        f"ceiling (feasible, replayed): {certificate['feasible']}/{count} = "
        f"{100 * certificate['ceiling']:.0f}%; not recoverable (screen): "
        f"{certificate['not_recoverable']}; open: {certificate['open']}",
        f"planner: {_planner_text(certificate)}; screen: {_screen_text(certificate)}",
        *_closed_loop_lines(certificate),
        *_witness_lines(certificate),
        "",
        "| seed | status | source | screen stroke / s_max | planner steps |",
        "|---|---|---|---|---|",
    ]
    for start in certificate["starts"]:
        fraction = start["screen_stroke_fraction"]
        stroke = "inf" if fraction is None else f"{fraction:.2f}"
        source = start_source(certificate, start) or "-"
        lines.append(
            f"| {start['seed']} | {start['status']} | {source} | {stroke} | "
            f"{start['planner_length']} |"
        )
    return "\n".join(lines) + "\n"


def _physics_title(certificate: JSONObject) -> str:
    randomize = certificate["env_kwargs"].get("randomize")
    if randomize is None:
        return ""
    return f", randomize={randomize if isinstance(randomize, str) else 'custom'}"


def _physics_lines(certificate: JSONObject) -> list[str]:
    block = certificate.get("randomize")
    if not isinstance(block, dict):
        return []
    ranges = ", ".join(
        f"{name} x {low:g}-{high:g}" for name, (low, high) in block["ranges"].items()
    )
    return [
        f"randomised physics ({ranges}): each start's parameters are drawn from its seed "
        "after the start, as gym.make(..., randomize=...) draws them; the screen, the "
        "planner, the witnesses and the replays use the start's drawn parameters "
        "(per start in certificate.json, 'params')",
        "",
    ]


def source_counts(certificate: JSONObject) -> dict[str, int]:
    """Feasible starts by source (:func:`start_source`), the planner's first, then by count."""
    counts: dict[str, int] = {}
    for start in certificate["starts"]:
        source = start_source(certificate, start)
        if source is not None:
            counts[source] = counts.get(source, 0) + 1
    planner = planner_name(certificate)
    return dict(sorted(counts.items(), key=lambda item: (item[0] != planner, -item[1], item[0])))


def sources_text(certificate: JSONObject) -> str:
    """ "ilqr 82, ppo_dock_n2 9": the feasible starts by source."""
    return ", ".join(f"{source} {count}" for source, count in source_counts(certificate).items())


def _witness_lines(certificate: JSONObject) -> list[str]:
    witnesses = certificate.get("witnesses")
    if not isinstance(witnesses, dict):
        return []
    runs = ", ".join(f"{run['source']} {run['solved']}/{run['tried']}" for run in witnesses["runs"])
    lines = [
        f"feasible by source: {sources_text(certificate)}",
        f"witnesses (solved/tried of the starts still open, in order): {runs}",
    ]
    closed = witnesses.get("closed_loop")
    if isinstance(closed, dict):
        lines.append(
            f"witnesses closed loop on {closed['integrator']} (rtol = atol = "
            f"{closed['tolerance']:g}): {closed['success']}/{closed['of']} witnessed starts "
            "still reached success with the policy re-run"
        )
    return lines


def _planner_text(certificate: JSONObject) -> str:
    """The planner's passes; a certificate written before the first pass was timed on its
    own (the Reverse-v0 ones) gives its total time only."""
    planner = certificate["planner"]
    total = (
        f"{planner.get('wall_time_s', '?')} s with up to {planner.get('restarts', '?')} restarts"
    )
    if "first_pass_safe" not in planner:
        return total
    return (
        f"{planner['first_pass_safe']}/{certificate['episodes']} safe in one pass "
        f"({planner.get('first_pass_wall_time_s', '?')} s), {total}"
    )


def _screen_text(certificate: JSONObject) -> str:
    screen = certificate["screen"]
    if screen.get("applied", True) is False:
        return "not applied (no screen proves a goal unreachable; no start is not recoverable)"
    return f"{screen['wall_time_s']} s"


def _closed_loop_lines(certificate: Mapping[str, object]) -> list[str]:
    closed = certificate.get("closed_loop")
    if not isinstance(closed, dict):
        return []
    return [
        f"closed loop on {closed['integrator']} (rtol = atol = {closed['tolerance']:g}): "
        f"{closed['success']}/{certificate['episodes']} reached the goal re-planning "
        f"({closed['wall_time_s']} s)"
    ]


#: Largest action record accepted (steps x action dimensions): Reverse's 400 steps.
_MAX_RECORD = 100_000


def actions_path(
    env_id: str,
    n_trailers: int,
    directory: Path = CERTIFICATES_DIR,
    randomize: str | None = None,
) -> Path:
    """Where the committed action records of a certificate live: ``<scene>_n<n>_actions.npz``
    (``<scene>_<preset>_n<n>_actions.npz`` under a randomisation preset; one float64
    array ``seed_<seed>`` per feasible start, one action per step)."""
    path = certificate_path(env_id, n_trailers, directory, randomize)
    return path.with_name(path.stem + "_actions.npz")


def write_actions(actions: dict[int, np.ndarray], path: Path) -> Path:
    """Write the action records of a certificate as one ``.npz`` (no pickles)."""
    arrays = {
        f"seed_{seed}": np.asarray(sequence, dtype=np.float64) for seed, sequence in actions.items()
    }
    with files.replacing(path) as temporary:
        np.savez_compressed(temporary, **arrays)  # type: ignore[arg-type]
    return path


def committed_actions(
    env_id: str,
    n_trailers: int,
    directory: Path = CERTIFICATES_DIR,
    randomize: str | None = None,
) -> dict[int, np.ndarray] | None:
    """The committed action records of ``env_id`` with ``n_trailers`` (and the preset
    ``randomize``; seed -> (T, d) float64 actions in [-1, 1]), or None when none are
    committed.

    Read with ``allow_pickle=False``: the file holds numbers only.

    Raises:
        ValueError: If the file holds anything but finite records in [-1, 1] named
            ``seed_<int>``.
    """
    path = actions_path(env_id, n_trailers, directory, randomize)
    if not path.is_file():
        return None
    return read_actions(path)


def records_beside(path: Path) -> Path:
    """Where the action records of the certificate file ``path`` live: ``actions.npz``
    beside a ``certificate.json`` (what ``agents.certify`` writes), else
    ``<stem>_actions.npz`` (a committed ``<scene>_n<n>.json``)."""
    if path.name == CERTIFICATE_JSON:
        return path.with_name(ACTIONS_ARCHIVE)
    return path.with_name(path.stem + "_actions.npz")


def planner_records(
    env_id: str, n_trailers: int, directory: Path = CERTIFICATES_DIR
) -> dict[int, np.ndarray] | None:
    """The committed records that the certificate's planner found (:func:`start_source` is
    its name), without the witnesses' (:mod:`agents.evaluation.witnesses`); None when no
    records are committed.

    Raises:
        ValueError: As :func:`committed_actions` and :func:`committed_certificate`.
    """
    records = committed_actions(env_id, n_trailers, directory)
    certificate = committed_certificate(env_id, n_trailers, directory)
    if records is None or certificate is None:
        return None
    planner = planner_name(certificate)
    kept = {s["seed"] for s in certificate["starts"] if start_source(certificate, s) == planner}
    return {seed: record for seed, record in records.items() if seed in kept}


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
