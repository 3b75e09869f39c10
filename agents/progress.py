"""Progress of the long commands: counts, elapsed time and an ETA, and the total wall time.

On a terminal the line is redrawn in place; otherwise (CI, a pipe, a log file) a step
prints one line, at most one per 5 % of the total, so that a log shows every phase
with its time without flooding. Output goes to
standard error, leaving standard output to the results (tables, paths).
"""

from __future__ import annotations

import sys
import time
from types import TracebackType
from typing import TextIO


def plural(count: int, noun: str, nouns: str | None = None) -> str:
    """``"1 step"``, ``"2 steps"``, ``"1 policy"`` (``nouns`` when the plural is not
    ``noun + "s"``)."""
    return f"{count} {noun if count == 1 else nouns or noun + 's'}"


def duration(seconds: float) -> str:
    """``"42 s"``, ``"3 min 05 s"``."""
    if seconds < 60:
        return f"{seconds:.0f} s" if seconds >= 10 else f"{seconds:.1f} s"
    minutes, rest = divmod(round(seconds), 60)
    return f"{minutes} min {rest:02d} s"


class Progress:
    """``with Progress(total, "evaluating") as bar: ... bar.advance("lqr")``.

    Args:
        total: The number of steps (phases, episodes, policies ...); the bar ends at it.
        label: What the command is doing.
        stream: Where to write (standard error by default).
        quiet: Write nothing.
    """

    def __init__(
        self, total: int, label: str, stream: TextIO | None = None, *, quiet: bool = False
    ) -> None:
        if total < 0:
            raise ValueError(f"total must be >= 0, got {total}")
        self.total = total
        self.label = label
        self.stream = stream or sys.stderr
        self.quiet = quiet
        self.done = 0
        self._printed = 0
        self.started = time.perf_counter()
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())

    def __enter__(self) -> Progress:
        self.started = time.perf_counter()
        if not self.tty:
            self._write(f"{self.label}: {plural(self.total, 'step')}")
        return self

    def advance(self, what: str = "", steps: int = 1) -> None:
        """Count ``steps`` more as done (``what`` names the one just finished)."""
        self.done = min(self.total, self.done + steps)
        elapsed = time.perf_counter() - self.started
        eta = elapsed / self.done * (self.total - self.done) if self.done else 0.0
        line = (
            f"{self.label}: [{self.done}/{self.total}] {what}".rstrip()
            + f" ({duration(elapsed)}, ETA {duration(eta)})"
        )
        if self.quiet:
            return
        if self.tty:
            self.stream.write("\r\033[K" + line)
            self.stream.flush()
        elif self.done == self.total or 20 * (self.done - self._printed) >= self.total:
            self._printed = self.done
            self._write(line)

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        trace: TracebackType | None,
    ) -> None:
        elapsed = duration(time.perf_counter() - self.started)
        if self.quiet:
            return
        if self.tty:
            self.stream.write("\r\033[K")
        outcome = "interrupted" if kind is not None else "done"
        self._write(f"{self.label}: {outcome}, {self.done}/{self.total} in {elapsed}")

    def _write(self, line: str) -> None:
        if self.quiet:
            return
        self.stream.write(line + "\n")
        self.stream.flush()
