"""Certificates: the typed record of certificate.json, its files, and the committed ones.

A certificate is read back only through :class:`Certificate` (``Certificate.from_json``):
every field has its JSON type, its counts are integers that add up, ``ceiling`` is the
feasible fraction of the starts, every start (:class:`CertificateStart`) has a seed of
its own and a known status (:data:`STATUSES`), and the stroke fractions are finite or
null; an unknown or malformed field is refused with a message naming it. Writing it
(``--overwrite`` included) replaces only the files the command writes
(:data:`CERTIFICATE_JSON`, :data:`CERTIFICATE_MD`, ``actions/seed_<seed>.npy``), each
atomically; any other file in the folder stays (an existing folder is written into only
with ``overwrite``).

An optional field (default None) is written only when it holds a value, so a document
read and written back is the document read (``schema_version`` added); the one null a
start writes is its replay's outcome (``replay_success`` for a goal scene's certificate,
``replay_safe`` for a survival scene's), null when the start was not replayed.
"""

from __future__ import annotations

import dataclasses
import io
import json
import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar, Final, Literal

import numpy as np

from agents.artifacts import files
from agents.artifacts.action_records import read_actions, write_actions
from agents.artifacts.records import DocumentError, JSONPart, JSONRecord

#: Committed certificates: ``certificate.json`` of the commands in docs/physics.md
#: section 14 (the per-start statuses; the action records are rebuilt by the command).
CERTIFICATES_DIR = Path(__file__).resolve().parent.parent / "certificates"


FEASIBLE: Final = "feasible"
NOT_RECOVERABLE: Final = "not recoverable"
OPEN: Final = "open"
#: Every status a start may have.
STATUSES = (FEASIBLE, NOT_RECOVERABLE, OPEN)
Status = Literal["feasible", "not recoverable", "open"]
#: The files of a certificate folder.
CERTIFICATE_JSON = "certificate.json"
CERTIFICATE_MD = "certificate.md"
ACTIONS = "actions"
#: Every record in one archive: the file to commit as ``<scene>_n<n>_actions.npz``.
ACTIONS_ARCHIVE = "actions.npz"
_ACTION_FILE = re.compile(r"seed_-?\d+\.npy")


def _optional_none(record: JSONRecord) -> set[str]:
    """The fields of ``record`` that default to None and hold None (not written)."""
    return {
        field.name
        for field in dataclasses.fields(record)
        if field.default is None and getattr(record, field.name) is None
    }


@dataclasses.dataclass(frozen=True, kw_only=True)
class _Part(JSONPart):
    """A part of a certificate: an optional field is written only when it holds a value."""

    def to_json(self) -> dict[str, object]:
        skipped = _optional_none(self)
        return {key: value for key, value in super().to_json().items() if key not in skipped}


@dataclasses.dataclass(frozen=True, kw_only=True)
class CertificateEnv(_Part):
    """``env_kwargs``: the gym.make keywords the certificate's scene was made with."""

    n_trailers: int
    #: A randomisation preset's name, or its ranges (None: nominal physics).
    randomize: str | Mapping[str, object] | None = None

    def __post_init__(self) -> None:
        if self.n_trailers < 0:
            raise DocumentError("env_kwargs.n_trailers must be an integer >= 0")

    def kwargs(self) -> dict[str, Any]:
        """The keywords as ``gym.make(env_id, **kwargs)`` takes them."""
        return self.to_json()

    @property
    def preset(self) -> str | None:
        """The randomisation preset's name (``custom`` for explicit ranges; None: nominal)."""
        if self.randomize is None or isinstance(self.randomize, str):
            return self.randomize
        return "custom"


@dataclasses.dataclass(frozen=True, kw_only=True)
class PlannerPart(_Part):
    """``planner``: the planner that searched every start and its settings."""

    #: ``ilqr``; None for the sampling planner (its certificates came before names).
    name: str | None = None
    samples: int | None = None
    horizon: int
    tail: int | None = None
    iterations: int
    elites: int | None = None
    seed: int | None = None
    restarts: int
    restart_rule: str | None = None
    #: iLQR's Jacobians of the step (:attr:`~agents.oracles.ilqr.ILQRConfig.jacobians`);
    #: None: the sampling planner, or an iLQR certificate written before the choice
    #: existed (differences).
    jacobians: str | None = None
    #: None on the Reverse-v0 certificates (written before the first pass was timed).
    first_pass_safe: int | None = None
    first_pass_wall_time_s: float | None = None
    simulated_steps_per_episode: float
    wall_time_s: float

    @property
    def label(self) -> str:
        """The planner's name (``mpc`` for the unnamed sampling planner)."""
        return self.name if self.name is not None else "mpc"


@dataclasses.dataclass(frozen=True, kw_only=True)
class ScreenPart(_Part):
    """``screen``: the survival screen that proves starts not recoverable."""

    horizon_s: float | None = None
    #: False where no screen applies (a goal scene); None (absent) means applied.
    applied: bool | None = None
    wall_time_s: float

    @property
    def is_applied(self) -> bool:
        """Whether the screen ran (every certificate but a goal scene's)."""
        return self.applied is not False


@dataclasses.dataclass(frozen=True, kw_only=True)
class ClosedLoopPart(_Part):
    """``closed_loop``: the planner re-planning on a finer plant, every start."""

    integrator: str
    tolerance: float
    planner: str
    success: int
    wall_time_s: float


@dataclasses.dataclass(frozen=True, kw_only=True)
class RandomizePart(_Part):
    """``randomize``: the randomised physics each start drew its parameters from."""

    preset: str | None
    ranges: Mapping[str, tuple[float, float]]
    meaning: str


@dataclasses.dataclass(frozen=True, kw_only=True)
class WitnessTally(_Part):
    """One witness policy's run over the starts still open when it came."""

    source: str
    tried: int
    solved: int
    #: Sampled witnesses: the draws per start and the seed they were drawn from.
    draws: int | None = None
    sample_seed: int | None = None


@dataclasses.dataclass(frozen=True, kw_only=True)
class WitnessClosedLoop(_Part):
    """The witnessed starts re-run closed loop on a finer plant."""

    integrator: str
    tolerance: float
    meaning: str
    success: int
    of: int


@dataclasses.dataclass(frozen=True, kw_only=True)
class WarmStartAttempt(_Part):
    """One planner pass of a warm start: its settings and what it solved."""

    restart: int
    horizon: int
    iterations: int
    rows: int
    solved: int


@dataclasses.dataclass(frozen=True, kw_only=True)
class WarmStartPass(_Part):
    """A warm-start run: policies' prefixes handed to the planner at split fractions."""

    specs: tuple[str, ...]
    splits: tuple[float, ...]
    open_before: int
    attempts: tuple[WarmStartAttempt, ...]
    wall_time_s: float


@dataclasses.dataclass(frozen=True, kw_only=True)
class WitnessesPart(_Part):
    """``witnesses``: the policies that solved starts the planner left open."""

    runs: tuple[WitnessTally, ...]
    success: str
    closed_loop: WitnessClosedLoop | None = None
    wall_time_s: float
    warm_starts: tuple[WarmStartPass, ...] | None = None
    #: A certificate written before warm-start passes accumulated kept its one pass here.
    warm_start: WarmStartPass | None = None

    def warm_start_passes(self) -> tuple[WarmStartPass, ...]:
        """The warm-start passes, oldest first (a lone earlier ``warm_start`` first)."""
        earlier = () if self.warm_start is None else (self.warm_start,)
        return (*earlier, *(self.warm_starts or ()))


@dataclasses.dataclass(frozen=True, kw_only=True)
class CertificateStart(_Part):
    """One start of a certificate: its status and how it was found."""

    DOCUMENT: ClassVar[str] = "certificate start"

    seed: int
    status: Status
    #: The screen's minimal stroke over s_max; None: no stroke (or no screen).
    screen_stroke_fraction: float | None
    planner_safe: bool
    planner_length: int
    planner_attempts: int | None = None
    #: The record replayed in a fresh env: reached success (goal) / stayed safe
    #: (survival); None: not replayed. One of the two per certificate.
    replay_success: bool | None = None
    replay_safe: bool | None = None
    closed_loop_success: bool | None = None
    #: The start's drawn physics under randomisation (``info['params']``).
    params: Mapping[str, float] | None = None
    #: Who found the record (a witness's label or the planner's name); feasible only.
    source: str | None = None
    actions_file: str | None = None
    witness_length: int | None = None
    warm_start_steps: int | None = None
    witness_draw: int | None = None
    witness_closed_loop_success: bool | None = None

    def __post_init__(self) -> None:
        fraction = self.screen_stroke_fraction
        if fraction is not None and not math.isfinite(fraction):
            raise DocumentError(
                f"seed {self.seed}: screen_stroke_fraction must be a finite number or null"
            )
        if self.planner_length < 0:
            raise DocumentError(f"seed {self.seed}: planner_length must be an integer >= 0")
        if self.source is not None and self.status != FEASIBLE:
            raise DocumentError(f"seed {self.seed}: source only on a feasible start")

    @property
    def feasible(self) -> bool:
        """Whether a record reaching the scene's end was found and replayed."""
        return self.status == FEASIBLE

    def document(self, goal: bool) -> dict[str, object]:
        """The start as JSON, its replay's outcome written under the scene's key
        (``replay_success`` for a goal scene, ``replay_safe`` for a survival one)."""
        document = self.to_json()
        replay = "replay_success" if goal else "replay_safe"
        document[replay] = getattr(self, replay)
        return document


@dataclasses.dataclass(frozen=True, kw_only=True)
class Certificate(JSONRecord):
    """certificate.json: a scene's ceiling, start by start (see the module docstring)."""

    DOCUMENT: ClassVar[str] = "certificate"

    env_id: str
    env_kwargs: CertificateEnv
    randomize: RandomizePart | None = None
    seeds: tuple[int, int]
    episodes: int
    planner: PlannerPart
    #: What a goal scene's replay reaches (None: a survival scene's certificate).
    success: str | None = None
    screen: ScreenPart
    feasible: int
    not_recoverable: int
    open: int
    ceiling: float
    screen_upper_estimate: float
    starts: tuple[CertificateStart, ...]
    closed_loop: ClosedLoopPart | None = None
    witnesses: WitnessesPart | None = None
    #: The feasible starts by who found them (:meth:`source_of`).
    sources: Mapping[str, int] | None = None

    def __post_init__(self) -> None:
        if not self.starts:
            raise DocumentError("starts must be a non-empty list")
        seeds = [start.seed for start in self.starts]
        if len(set(seeds)) != len(seeds):
            raise DocumentError("starts: every seed must appear once")
        if self.episodes != len(self.starts):
            raise DocumentError(f"episodes must be the number of starts ({len(self.starts)})")
        for name, status in (
            ("feasible", FEASIBLE),
            ("not_recoverable", NOT_RECOVERABLE),
            ("open", OPEN),
        ):
            count = sum(start.status == status for start in self.starts)
            if getattr(self, name) != count:
                raise DocumentError(f"{name} must be the number of {status!r} starts ({count})")
        if self.sources is not None and dict(self.sources) != self._found_by():
            raise DocumentError(
                f"sources must count the feasible starts by source ({self._found_by()})"
            )
        if not math.isclose(self.ceiling, self.feasible / len(self.starts), abs_tol=1e-9):
            raise DocumentError("ceiling must be the feasible fraction of the starts")

    @property
    def n_trailers(self) -> int:
        """The number of trailers the certificate's scene was made with."""
        return self.env_kwargs.n_trailers

    @property
    def goal(self) -> bool:
        """Whether this is a goal scene's certificate (a replay reaches success)."""
        return self.success is not None

    def source_of(self, start: CertificateStart) -> str | None:
        """Who found a start's record: its ``source``, the planner's name for a feasible
        start of a certificate written before sources were kept, None for a start that
        is not feasible."""
        if not start.feasible:
            return None
        return start.source if start.source is not None else self.planner.label

    def _found_by(self) -> dict[str, int]:
        found: dict[str, int] = {}
        for start in self.starts:
            source = self.source_of(start)
            if source is not None:
                found[source] = found.get(source, 0) + 1
        return found

    def source_counts(self) -> dict[str, int]:
        """Feasible starts by source, the planner's first, then by count."""
        planner = self.planner.label
        return dict(
            sorted(
                self._found_by().items(),
                key=lambda item: (item[0] != planner, -item[1], item[0]),
            )
        )

    def sources_text(self) -> str:
        """ "ilqr 82, ppo_dock_n2 9": the feasible starts by source."""
        return ", ".join(f"{source} {count}" for source, count in self.source_counts().items())

    def by_seed(self) -> dict[int, CertificateStart]:
        """The starts by seed."""
        return {start.seed: start for start in self.starts}

    def with_starts(
        self,
        starts: tuple[CertificateStart, ...],
        *,
        sources: bool | None = None,
        **changes: object,
    ) -> Certificate:
        """A copy with ``starts``, their counts and ceiling recomputed, and ``changes`` (other
        fields to replace); ``sources``: whether it counts the feasible starts by source
        (:meth:`source_counts`; None: where this one does)."""
        count = len(starts)
        feasible = sum(start.status == FEASIBLE for start in starts)
        unrecoverable = sum(start.status == NOT_RECOVERABLE for start in starts)
        counted = self.replace(
            starts=starts,
            sources=None,
            episodes=count,
            feasible=feasible,
            not_recoverable=unrecoverable,
            open=count - feasible - unrecoverable,
            ceiling=feasible / count,
            **changes,
        )
        keep = self.sources is not None if sources is None else sources
        return counted.replace(sources=counted.source_counts()) if keep else counted

    def to_json(self) -> dict[str, object]:
        skipped = _optional_none(self)
        document = {key: value for key, value in super().to_json().items() if key not in skipped}
        document["starts"] = [start.document(self.goal) for start in self.starts]
        return document


@dataclasses.dataclass(frozen=True)
class Certified:
    """A certificate and the action records of its feasible starts (seed -> (T, d)
    float64 actions in [-1, 1]): what certification returns and writes."""

    certificate: Certificate
    actions: Mapping[int, np.ndarray]


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


def write_certificate(certified: Certified, out: Path, overwrite: bool) -> Certificate:
    """Write certificate.json, certificate.md, actions/seed_<seed>.npy and actions.npz (the
    same records in one archive, the file that is committed beside a certificate as
    ``<scene>_n<n>_actions.npz``) under ``out``. Returns the certificate written (each
    feasible start's ``actions_file`` set).

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
    actions = certified.actions
    certificate = certified.certificate.replace(
        starts=tuple(
            start.replace(actions_file=f"{ACTIONS}/seed_{start.seed}.npy")
            if start.feasible
            else start
            for start in certified.certificate.starts
        )
    )
    keep = {f"seed_{seed}.npy" for seed in actions}
    for path in own_files(out):
        if path.parent.name == ACTIONS and path.name not in keep:
            path.unlink()
    for seed, sequence in actions.items():
        buffer = io.BytesIO()
        np.save(buffer, np.asarray(sequence), allow_pickle=False)
        files.atomic_write_bytes(out / ACTIONS / f"seed_{seed}.npy", buffer.getvalue())
    write_actions(actions, out / ACTIONS_ARCHIVE)
    files.atomic_write_text(out / CERTIFICATE_MD, markdown(certificate))
    files.atomic_write_text(
        out / CERTIFICATE_JSON, json.dumps(certificate.to_json(), indent=2) + "\n"
    )
    return certificate


def read_certificate(path: Path) -> Certificate:
    """A certificate file, checked (:meth:`Certificate.from_json`).

    Raises:
        ValueError: If it is too large, not JSON, or not a valid certificate.
    """
    return Certificate.from_json(files.read_json(path, "certificate"), str(path))


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
) -> Certificate | None:
    """The committed certificate of ``env_id`` with ``n_trailers`` (and the randomisation
    preset ``randomize``; None: nominal physics), or None.

    Raises:
        ValueError: If the file is not a certificate of that scene, n and randomisation.
    """
    path = certificate_path(env_id, n_trailers, directory, randomize)
    if not path.is_file():
        return None
    certificate = read_certificate(path)
    if (
        certificate.env_id != env_id
        or certificate.n_trailers != n_trailers
        or certificate.env_kwargs.randomize != randomize
    ):
        physics = "nominal physics" if randomize is None else f"randomize={randomize}"
        raise ValueError(
            f"{path} is not a certificate of {env_id} with n = {n_trailers} and {physics}"
        )
    return certificate


def markdown(certificate: Certificate) -> str:
    """The certificate's summary and per-start table in Markdown."""
    count = certificate.episodes
    first, last = certificate.seeds
    preset = certificate.env_kwargs.preset
    lines = [
        f"# {certificate.env_id}, n = {certificate.n_trailers}, seeds {first}-{last}"
        + ("" if preset is None else f", randomize={preset}"),
        "",
        *_physics_lines(certificate.randomize),
        f"ceiling (feasible, replayed): {certificate.feasible}/{count} = "
        f"{100 * certificate.ceiling:.0f}%; not recoverable (screen): "
        f"{certificate.not_recoverable}; open: {certificate.open}",
        f"planner: {_planner_text(certificate)}; screen: {_screen_text(certificate.screen)}",
        *_closed_loop_lines(certificate),
        *_witness_lines(certificate),
        "",
        "| seed | status | source | screen stroke / s_max | planner steps |",
        "|---|---|---|---|---|",
    ]
    for start in certificate.starts:
        fraction = start.screen_stroke_fraction
        stroke = "inf" if fraction is None else f"{fraction:.2f}"
        source = certificate.source_of(start) or "-"
        lines.append(
            f"| {start.seed} | {start.status} | {source} | {stroke} | {start.planner_length} |"
        )
    return "\n".join(lines) + "\n"


def _physics_lines(block: RandomizePart | None) -> list[str]:
    if block is None:
        return []
    ranges = ", ".join(f"{name} x {low:g}-{high:g}" for name, (low, high) in block.ranges.items())
    return [
        f"randomised physics ({ranges}): each start's parameters are drawn from its seed "
        "after the start, as gym.make(..., randomize=...) draws them; the screen, the "
        "planner, the witnesses and the replays use the start's drawn parameters "
        "(per start in certificate.json, 'params')",
        "",
    ]


def _witness_lines(certificate: Certificate) -> list[str]:
    witnesses = certificate.witnesses
    if witnesses is None:
        return []
    runs = ", ".join(f"{run.source} {run.solved}/{run.tried}" for run in witnesses.runs)
    lines = [
        f"feasible by source: {certificate.sources_text()}",
        f"witnesses (solved/tried of the starts still open, in order): {runs}",
    ]
    closed = witnesses.closed_loop
    if closed is not None:
        lines.append(
            f"witnesses closed loop on {closed.integrator} (rtol = atol = "
            f"{closed.tolerance:g}): {closed.success}/{closed.of} witnessed starts "
            "still reached success with the policy re-run"
        )
    return lines


def _planner_text(certificate: Certificate) -> str:
    """The planner's passes; a certificate written before the first pass was timed on its
    own (the Reverse-v0 ones) gives its total time only."""
    planner = certificate.planner
    total = f"{planner.wall_time_s} s with up to {planner.restarts} restarts"
    if planner.first_pass_safe is None:
        return total
    first = "?" if planner.first_pass_wall_time_s is None else planner.first_pass_wall_time_s
    return f"{planner.first_pass_safe}/{certificate.episodes} safe in one pass ({first} s), {total}"


def _screen_text(screen: ScreenPart) -> str:
    if not screen.is_applied:
        return "not applied (no screen proves a goal unreachable; no start is not recoverable)"
    return f"{screen.wall_time_s} s"


def _closed_loop_lines(certificate: Certificate) -> list[str]:
    closed = certificate.closed_loop
    if closed is None:
        return []
    return [
        f"closed loop on {closed.integrator} (rtol = atol = {closed.tolerance:g}): "
        f"{closed.success}/{certificate.episodes} reached the goal re-planning "
        f"({closed.wall_time_s} s)"
    ]


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
    """The committed records that the certificate's planner found (:meth:`Certificate.source_of`
    is its name), without the witnesses' (:mod:`agents.certification.witnesses`); None when no
    records are committed.

    Raises:
        ValueError: As :func:`committed_actions` and :func:`committed_certificate`.
    """
    records = committed_actions(env_id, n_trailers, directory)
    certificate = committed_certificate(env_id, n_trailers, directory)
    if records is None or certificate is None:
        return None
    planner = certificate.planner.label
    kept = {s.seed for s in certificate.starts if certificate.source_of(s) == planner}
    return {seed: record for seed, record in records.items() if seed in kept}
