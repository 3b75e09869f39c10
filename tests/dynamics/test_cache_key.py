"""The kernels' disk caches are keyed on a hash of every kernel source (dynamics._cache).

An edit to a helper that a kernel inlines from another file recompiles the kernel, an
unedited tree loads it from the cache, and no compiled function of the kernel trees is
keyed any other way.
"""

from __future__ import annotations

import ast
import hashlib
import importlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from numba.core.caching import NullCache
from numba.core.registry import CPUDispatcher

from dynamics._cache import KERNEL_TREES, ROOT, SOURCE_HASH, cached_njit, source_hash


def _kernel_sources() -> list[Path]:
    return [path for tree in KERNEL_TREES for path in sorted((ROOT / tree).rglob("*.py"))]


def test_the_hash_covers_the_path_and_bytes_of_every_python_file(tmp_path: Path) -> None:
    (tmp_path / "pkg" / "sub").mkdir(parents=True)
    (tmp_path / "pkg" / "a.py").write_bytes(b"x = 1\n")
    (tmp_path / "pkg" / "sub" / "b.py").write_bytes(b"y = 2\n")
    (tmp_path / "pkg" / "notes.txt").write_bytes(b"not a source")
    expected = hashlib.sha256(b"pkg/a.py\0x = 1\n\0pkg/sub/b.py\0y = 2\n\0").hexdigest()
    assert source_hash(tmp_path, ("pkg", "missing")) == expected
    (tmp_path / "pkg" / "sub" / "b.py").write_bytes(b"y = 3\n")
    assert source_hash(tmp_path, ("pkg",)) != expected


def test_the_key_is_the_hash_of_the_kernel_trees() -> None:
    assert KERNEL_TREES == ("dynamics", "trailer_env", "agents/oracles")
    assert source_hash(ROOT, KERNEL_TREES) == SOURCE_HASH
    assert ROOT / "dynamics" / "_kernel.py" in _kernel_sources()
    assert ROOT / "agents" / "oracles" / "ilqr_kernels.py" in _kernel_sources()


def test_no_kernel_source_asks_numba_for_its_own_cache() -> None:
    """``njit(cache=True)`` would key on its own file only; every cached kernel uses cached_njit."""
    offenders = []
    for path in _kernel_sources():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and any(kw.arg == "cache" for kw in node.keywords):
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert offenders == []


def _decorated_with_cached_njit(path: Path) -> int:
    """How many functions of ``path`` are decorated ``@cached_njit(...)``."""
    return sum(
        isinstance(decorator, ast.Call) and getattr(decorator.func, "id", None) == "cached_njit"
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
        if isinstance(node, ast.FunctionDef)
        for decorator in node.decorator_list
    )


def test_every_compiled_function_of_the_kernel_trees_is_keyed_on_the_hash() -> None:
    keyed, uncached = 0, 0
    decorated = sum(_decorated_with_cached_njit(path) for path in _kernel_sources())
    for path in _kernel_sources():
        name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
        if name.endswith("__main__"):
            continue  # a command line, no kernels
        module = importlib.import_module(name.removesuffix(".__init__"))
        for value in vars(module).values():
            if not isinstance(value, CPUDispatcher) or value.py_func.__module__ != module.__name__:
                continue
            if isinstance(value._cache, NullCache):
                uncached += 1  # compiled once per process (dopri's inner helpers)
            else:
                assert value._cache._cache_file._source_stamp == SOURCE_HASH, value
                keyed += 1
    assert (keyed, uncached) == (decorated, 4) and decorated > 80


def test_cached_njit_refuses_its_own_option_and_functions_outside_the_trees() -> None:
    with pytest.raises(TypeError, match="sets the cache itself; do not pass cache="):
        cached_njit(cache=True)

    def outside(x: float) -> float:
        return x

    with pytest.raises(ValueError, match="outside the kernel trees") as error:
        cached_njit()(outside)
    assert __file__ in str(error.value)


_HELPER = """from dynamics.jit import cached_njit


@cached_njit(inline="always")
def helper(x):
    return x + 1.0
"""
_CALLERS = """from numba import njit

from dynamics._probe_helper import helper
from dynamics.jit import cached_njit


@cached_njit()
def caller(x):
    return 2.0 * helper(x)


@njit(cache=True)  # numba's own key: this file's stamp only
def plain_caller(x):
    return 2.0 * helper(x)
"""
_RUN = """from dynamics._probe import caller, plain_caller
for f in (caller, plain_caller):
    value = f(1.0)
    print(value, len(f.stats.cache_hits), len(f.stats.cache_misses))
"""


def _run(tree: Path) -> list[tuple[float, int, int]]:
    """(result, cache hits, cache misses) of caller and plain_caller in a fresh process."""
    env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_CACHE_DIR": str(tree / "cache")}
    done = subprocess.run(
        [sys.executable, "-c", _RUN],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    )
    rows = [line.split() for line in done.stdout.splitlines()]
    return [(float(value), int(hits), int(misses)) for value, hits, misses in rows]


def test_editing_an_inlined_helper_recompiles_its_caller(tmp_path: Path) -> None:
    """A copy of ``dynamics`` with a caller and the helper it inlines from another file."""
    package = tmp_path / "dynamics"
    shutil.copytree(ROOT / "dynamics", package, ignore=shutil.ignore_patterns("__pycache__"))
    (package / "_probe_helper.py").write_text(_HELPER)
    (package / "_probe.py").write_text(_CALLERS)

    assert _run(tmp_path) == [(4.0, 0, 1), (4.0, 0, 1)]  # compiled, saved
    assert _run(tmp_path) == [(4.0, 1, 0), (4.0, 1, 0)]  # unedited: loaded from the cache
    (package / "_probe_helper.py").write_text(_HELPER.replace("x + 1.0", "x + 2.0"))
    # The hash sees the edit: recompiled. numba's own key does not: the stale result.
    assert _run(tmp_path) == [(6.0, 0, 1), (4.0, 1, 0)]
