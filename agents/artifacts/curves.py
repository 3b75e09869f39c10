"""Learning curves (evaluations.csv): their columns, reading them back, writing them.

A curve is rewritten atomically (:func:`write_curve`) or appended to one row at a
time (:func:`append_rows`; a training adds a row per evaluation). A run killed while
appending may leave a cut last line (no newline at its end): :func:`read_curve`
drops such a line instead of failing, and refuses (``ValueError``, naming the line)
any other row that is not numbers under the file's header. A resumed run keeps its
earlier rows as they were written (:func:`keep_rows`) and appends its own.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from agents.artifacts import files

#: The column every curve has: the environment steps (or labels) of each row.
STEPS_COLUMN = "timesteps"
#: Columns of evaluations.csv.
CURVE_COLUMNS = (
    "timesteps",
    "wall_s",
    "mean_return",
    "jackknife_rate",
    "safe_rate",
    "band_time_fraction",
    "min_margin_mean",
    "success_rate",
)
#: The largest curve file read (a row is about 100 bytes).
MAX_CURVE_BYTES = 64 * 2**20


def read_curve(
    path: Path, columns: Sequence[str] = ("timesteps",), *, header: Sequence[str] | None = None
) -> list[dict[str, float]]:
    """Rows of an evaluations.csv as dicts of floats (empty if the file is absent).

    A cut last line (no final newline, a field short or unparseable) is dropped.
    ``header``: the exact header the file must have (a run that appends rows to it).

    Raises:
        ValueError: If the file is too large, lacks one of ``columns`` (or its header is
            not ``header``), or a row (other than a cut last one) is not numbers.
    """
    return [row for _, row in _parsed(path, columns, header)[1]]


def keep_rows(
    path: Path, keep: Callable[[dict[str, float]], bool], columns: Sequence[str] = ("timesteps",)
) -> list[dict[str, float]]:
    """Keep the rows of a curve for which ``keep`` holds; returns them.

    The header and the kept lines stay as they were written (``800`` is not rewritten
    ``800.0``); a cut last line is dropped. The file is rewritten (atomically) only when
    that changes it.

    Raises:
        ValueError: As :func:`read_curve`.
    """
    head, lines = _parsed(path, columns, None)
    kept = [(line, row) for line, row in lines if keep(row)]
    text = head + "".join(line if line.endswith("\n") else line + "\n" for line, _ in kept)
    if head and text.encode("utf-8") != path.read_bytes():
        files.atomic_write_text(path, text)
    return [row for _, row in kept]


def _parsed(
    path: Path, columns: Sequence[str], exact: Sequence[str] | None
) -> tuple[str, list[tuple[str, dict[str, float]]]]:
    """The header line of a curve and its rows, each with its line (see :func:`read_curve`)."""
    if not path.is_file():
        return "", []
    size = path.stat().st_size
    if size > MAX_CURVE_BYTES:
        raise ValueError(f"curve {path} is {size} bytes, over the limit of {MAX_CURVE_BYTES}")
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as error:
        raise ValueError(f"curve {path} is not UTF-8 text: {error}") from None
    lines = text.splitlines(keepends=True)
    if not lines:
        return "", []
    try:
        header = next(csv.reader([lines[0]]))
    except csv.Error as error:
        raise ValueError(f"curve {path}: unreadable header: {error}") from None
    missing = [column for column in ("timesteps", *columns) if column not in header]
    if missing or len(set(header)) != len(header):
        raise ValueError(
            f"curve {path}: its header {header[:8]!r:.120} lacks {missing or 'unique names'}"
        )
    if exact is not None and header != list(exact):
        raise ValueError(f"curve {path}: its header {header!r:.120} is not {list(exact)!r:.120}")
    rows: list[tuple[str, dict[str, float]]] = []
    for number, line in enumerate(lines[1:], start=2):
        cut = number == len(lines) and not line.endswith(("\n", "\r"))
        try:
            fields = next(csv.reader([line]), [])
            if not fields:
                continue
            if len(fields) != len(header):
                raise ValueError(f"{len(fields)} fields, not {len(header)}")
            row = {key: float(value) for key, value in zip(header, fields, strict=True)}
            if not math.isfinite(row[STEPS_COLUMN]):
                raise ValueError("timesteps is not finite")
        except (ValueError, csv.Error) as error:
            if cut:
                break  # the last row, cut while it was written
            raise ValueError(f"curve {path}, line {number}: {error}") from None
        rows.append((line, row))
    head = lines[0] if lines[0].endswith("\n") else lines[0] + "\n"
    return head, rows


def _csv_text(rows: Sequence[Mapping[str, object]], fieldnames: Sequence[str], header: bool) -> str:
    buffer = io.StringIO()
    writer = csv.DictWriter(
        buffer, fieldnames=list(fieldnames), lineterminator="\n", extrasaction="ignore"
    )
    if header:
        writer.writeheader()
    writer.writerows(rows)
    return buffer.getvalue()


def write_curve(
    path: Path,
    rows: Sequence[Mapping[str, object]],
    fieldnames: Sequence[str] = (*CURVE_COLUMNS, "iteration", "loss"),
) -> None:
    """Write a whole curve atomically (a CSV with ``fieldnames`` as its header)."""
    files.atomic_write_text(path, _csv_text(rows, fieldnames, header=True))


def append_rows(
    path: Path, rows: Sequence[Mapping[str, object]], fieldnames: Sequence[str] = CURVE_COLUMNS
) -> None:
    """Append rows to a curve (with the header when the file starts).

    A cut last line left by a killed run is cut off first, so that the new rows start
    on their own line.

    Raises:
        UnsafeFileError: If ``path`` is a symbolic link.
    """
    files.refuse_symlink(path)
    if not path.is_file():
        write_curve(path, rows, fieldnames)
        return
    with path.open("rb+") as handle:
        content = handle.read()
        if content and not content.endswith(b"\n"):
            handle.truncate(content.rfind(b"\n") + 1)
        handle.seek(0, io.SEEK_END)
        handle.write(_csv_text(rows, fieldnames, header=False).encode("utf-8"))
        handle.flush()
        os.fsync(handle.fileno())
