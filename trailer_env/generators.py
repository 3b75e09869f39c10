"""Per-environment random generators, held so compiled code can draw from them.

Every environment draws its starting states from its own :class:`numpy.random.Generator`
(which is what lets the vector env replay single environments). numba's nopython mode
accepts NumPy generators and advances the same bit-generator state NumPy does, with the
same algorithms (``random``, ``uniform``, ``standard_normal``): a start drawn in
compiled code is the start NumPy would draw, bit for bit, and the Python generator's
stream continues from where the compiled draws left it. Passing N generators to a
compiled function one by one costs an unboxing each; :class:`GeneratorBank` keeps them
in a ``numba.typed.List`` as well, which crosses into compiled code at a cost that does
not grow with N (the times: benchmarks/README.md, "Figures quoted from the code").
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np
from numba.typed import List


class GeneratorBank(Sequence[np.random.Generator]):
    """A list of generators (indexed like one) and its ``numba.typed.List`` twin.

    Args:
        generators: One generator per environment (not copied: drawing from the bank
            advances them).

    Raises:
        TypeError: If an entry is not a :class:`numpy.random.Generator`.
    """

    def __init__(self, generators: Sequence[np.random.Generator]) -> None:
        self._python = list(generators)
        for generator in self._python:
            _check_generator(generator)
        self._typed: List | None = None

    def __len__(self) -> int:
        return len(self._python)

    def __getitem__(self, i: int) -> np.random.Generator:  # type: ignore[override]
        return self._python[i]

    def __iter__(self) -> Iterator[np.random.Generator]:
        return iter(self._python)

    def __setitem__(self, i: int, generator: np.random.Generator) -> None:
        _check_generator(generator)
        self._python[i] = generator
        if self._typed is not None:
            self._typed[i] = generator

    def __getstate__(self) -> dict[str, object]:
        # A typed List does not pickle; it is rebuilt from the generators on first use.
        return {"_python": self._python, "_typed": None}

    def __setstate__(self, state: dict[str, object]) -> None:
        self.__dict__.update(state)

    @property
    def typed(self) -> List:
        """The generators as a ``numba.typed.List`` (built on first use, then kept in step)."""
        if self._typed is None:
            self._typed = List(self._python)
        return self._typed


def _check_generator(generator: object) -> None:
    if not isinstance(generator, np.random.Generator):
        raise TypeError(f"expected a numpy.random.Generator, got {type(generator).__name__}")


def typed_generators(generators: Sequence[np.random.Generator]) -> List:
    """``generators`` as a ``numba.typed.List`` (the bank's own list when it is a bank)."""
    if isinstance(generators, GeneratorBank):
        return generators.typed
    return GeneratorBank(generators).typed
