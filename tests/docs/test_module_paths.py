"""Every dotted module path the docs and docstrings name imports.

A name is a dotted path that starts with one of the project's packages (``agents.``,
``trailer_env.``, ``dynamics.``, ``benchmarks.``), such as ``agents.oracles.planner`` or
``trailer_env.core.ShapedCore.shaping_penalties``: the longest importable prefix is
imported and the rest is looked up attribute by attribute. An attribute that an instance
gets in ``__init__`` counts when a class on the way declares it (an annotation) or
assigns it (``self.<name> =`` in its source). Names are collected from README.md,
CONTRIBUTING.md, benchmarks/README.md and docs/**/*.md, and from the string literals
(docstrings, help texts) and comments of every module of the four packages.
"""

from __future__ import annotations

import importlib
import inspect
import io
import re
import tokenize
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("agents", "trailer_env", "dynamics", "benchmarks")
# Not preceded by a path or another name (``docs/agents.md``, ``np.dynamics``).
_NAME = re.compile(rf"(?<![\w/.\-])(?:{'|'.join(PACKAGES)})(?:\.[A-Za-z_]\w*)+")
# ``agents.md``, ``dynamics.py``: file names, not module paths.
_FILE_SUFFIXES = frozenset({"md", "py", "json", "zip", "npz", "yml", "yaml", "txt", "png"})


def names_in(text: str) -> list[str]:
    """The dotted module paths named in ``text``, in order (repeats kept)."""
    return [
        match.group(0)
        for match in _NAME.finditer(text)
        if match.group(0).rsplit(".", 1)[1] not in _FILE_SUFFIXES
    ]


def _source_texts() -> list[tuple[str, str]]:
    """(where, text) of every Markdown page and every string or comment of the packages."""
    pages = [ROOT / "README.md", ROOT / "CONTRIBUTING.md", ROOT / "benchmarks" / "README.md"]
    pages += sorted((ROOT / "docs").rglob("*.md"))
    texts = [(str(page.relative_to(ROOT)), page.read_text(encoding="utf-8")) for page in pages]
    for package in PACKAGES:
        for module in sorted((ROOT / package).rglob("*.py")):
            source = module.read_text(encoding="utf-8")
            where = str(module.relative_to(ROOT))
            for token in tokenize.generate_tokens(io.StringIO(source).readline):
                if token.type in (tokenize.STRING, tokenize.COMMENT):
                    texts.append((f"{where}:{token.start[0]}", token.string))
    return texts


def _declares(owner: object, attribute: str) -> bool:
    """Whether a class of ``owner``'s MRO annotates or assigns ``self.<attribute>``."""
    if not isinstance(owner, type):
        return False
    assignment = re.compile(rf"\bself\.{re.escape(attribute)}\s*(?::[^=\n]+)?=(?!=)")
    for klass in owner.__mro__:
        if attribute in vars(klass).get("__annotations__", {}):
            return True
        try:
            source = inspect.getsource(klass)
        except (OSError, TypeError):  # builtins and classes without a source file
            continue
        if assignment.search(source):
            return True
    return False


def unresolved(name: str) -> str | None:
    """Why ``name`` does not resolve (None when it does)."""
    parts = name.split(".")
    module: ModuleType | None = None
    for end in range(len(parts), 0, -1):
        prefix = ".".join(parts[:end])
        try:
            module = importlib.import_module(prefix)
        except ModuleNotFoundError as error:
            # Only the named module itself may be missing; a missing dependency is a failure.
            if error.name is None or not prefix.startswith(error.name):
                raise
            continue
        break
    if module is None:
        return f"no module {parts[0]}"
    owner: object = module
    for depth in range(end, len(parts)):
        attribute = parts[depth]
        if hasattr(owner, attribute):
            owner = getattr(owner, attribute)
        elif depth == len(parts) - 1 and _declares(owner, attribute):
            return None
        else:
            return f"{'.'.join(parts[:depth])} has no attribute {attribute!r}"
    return None


def test_names_are_found_in_prose_and_not_in_file_names() -> None:
    text = (
        "see `agents.oracles.planner` (docs/agents.md, agents.md), run python -m "
        "agents.train --backend rllib; trailer_env/Reverse-v1 and dynamics.jit.cached_njit."
    )
    assert names_in(text) == ["agents.oracles.planner", "agents.train", "dynamics.jit.cached_njit"]


def test_the_resolver_refuses_removed_modules_and_missing_attributes() -> None:
    assert unresolved("agents.oracles.screen") is None
    assert unresolved("trailer_env.core.ShapedCore.shaping_penalties") is None  # set in __init__
    assert unresolved("agents.metrics") == "agents has no attribute 'metrics'"
    assert unresolved("agents.oracles.planner.NoSuchThing") == (
        "agents.oracles.planner has no attribute 'NoSuchThing'"
    )
    assert unresolved("trailer_env.core.ShapedCore.shaping_constants") == (
        "trailer_env.core.ShapedCore has no attribute 'shaping_constants'"
    )


def test_every_named_module_path_resolves() -> None:
    first_seen: dict[str, str] = {}
    for where, text in _source_texts():
        for name in names_in(text):
            first_seen.setdefault(name, where)
    assert len(first_seen) > 150  # the scan reads the docs, not an empty list
    broken = [
        f"{name} ({where}): {problem}"
        for name, where in sorted(first_seen.items())
        if (problem := unresolved(name)) is not None
    ]
    assert not broken, "\n".join(broken)
