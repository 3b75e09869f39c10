"""Per-environment info dicts built only when read (SB3's list-of-dicts ``infos``).

SB3's ``VecEnv.step`` returns one info dict per environment, and building N dicts of
Python scalars every step cost the SB3 adapter most of its throughput (the figures:
benchmarks/README.md, "Figures quoted from the code"). :class:`BatchInfos` is a sequence
that holds the step's info arrays (copies) and the extra entries of the environments that
ended, and builds environment i's dict the first time it is read (then keeps it: SB3 and
VecNormalize write into them). Reading all of them costs what building them did; reading a
few (the environments that ended, which is what SB3's algorithms and wrappers do outside
their episode-statistics loop) costs only those.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import overload

import numpy as np


class BatchInfos(Sequence[dict[str, object]]):
    """The infos of one step of N environments, as a read-mostly sequence of dicts.

    Args:
        columns: Info key -> (N,) array (not copied: pass arrays nothing else writes).
        extras: Row -> extra entries for that row (``terminal_observation`` ...).
        count: N.
    """

    __slots__ = ("_columns", "_count", "_dicts", "_extras", "_lists")

    def __init__(
        self, columns: dict[str, object], extras: dict[int, dict[str, object]], count: int
    ):
        self._columns = columns
        self._extras = extras
        self._count = count
        self._dicts: list[dict[str, object] | None] = [None] * count
        self._lists: list[list[object]] | None = None

    def __len__(self) -> int:
        return self._count

    def column(self, key: str) -> object:
        """The step's values of ``key`` for every environment (the (N,) array, not a copy:
        read it, do not write it), without building any dict. Writes into the dicts of
        :meth:`__getitem__` are not seen here.

        Raises:
            KeyError: If the step has no such info.
        """
        return self._columns[key]

    def _build(self, i: int) -> dict[str, object]:
        if self._lists is None:  # Python scalars, as the dicts held before
            self._lists = [_per_row(column) for column in self._columns.values()]
        info = {key: values[i] for key, values in zip(self._columns, self._lists, strict=True)}
        extra = self._extras.get(i)
        if extra:
            info.update(extra)
        self._dicts[i] = info
        return info

    @overload
    def __getitem__(self, index: int) -> dict[str, object]: ...

    @overload
    def __getitem__(self, index: slice) -> list[dict[str, object]]: ...

    def __getitem__(self, index: int | slice) -> dict[str, object] | list[dict[str, object]]:
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(self._count))]
        i = index.__index__()
        if i < 0:
            i += self._count
        if not 0 <= i < self._count:
            raise IndexError(f"info index {index} out of range for {self._count} environments")
        info = self._dicts[i]
        return info if info is not None else self._build(i)

    def __iter__(self) -> Iterator[dict[str, object]]:
        for i in range(self._count):
            info = self._dicts[i]
            yield info if info is not None else self._build(i)

    def __eq__(self, other: object) -> bool:
        if isinstance(other, (list, BatchInfos)):
            if len(other) != self._count:
                return False
            return all(a == b for a, b in zip(self, other, strict=True))
        return NotImplemented

    def __repr__(self) -> str:
        return f"BatchInfos({list(self)!r})"


def _per_row(column: object) -> list[object]:
    """A column's values per row: an array's Python scalars, or, for a dict of arrays
    (``params``), one dict of Python scalars per row."""
    if isinstance(column, dict):
        names = list(column)
        values = [np.asarray(column[name]).tolist() for name in names]
        return [dict(zip(names, row, strict=True)) for row in zip(*values, strict=True)]
    return list(np.asarray(column).tolist())
