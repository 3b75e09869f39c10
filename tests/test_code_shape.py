"""The code stays in rooms one can hold in the head: typed documents, short modules and functions.

The counts are those of CONTRIBUTING.md ("Code shape"): untyped values (``Any`` and the
``JSONObject`` alias of ``dict[str, Any]``) in the three packages, string-key reads
(``x["key"]`` and ``x.get("key")``) in agents/, non-test modules over 700 lines, and
functions over 100 lines. A document read by string key, a module that grows past a
sitting or a function past a screenful fails here, naming where.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("dynamics", "trailer_env", "agents")
UNTYPED = re.compile(r"\bAny\b|\bJSONObject\b")
STRING_KEY = re.compile(r'\[\s*"[A-Za-z_0-9]+"\s*\]|\.get\(\s*"[A-Za-z_0-9]+"')
#: The compiled kernel is one numba module by design (its functions call each other inline).
LONG_MODULES_ALLOWED = {"dynamics/_kernel.py"}
MAX_UNTYPED = 150
MAX_STRING_KEYS = 150
MAX_MODULE_LINES = 700
MAX_FUNCTION_LINES = 100
MAX_LONG_FUNCTIONS = 5


def sources(*packages: str) -> list[Path]:
    return sorted(path for package in packages for path in (ROOT / package).rglob("*.py"))


def name(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def test_untyped_values_are_rare() -> None:
    counts = {name(path): len(UNTYPED.findall(path.read_text())) for path in sources(*PACKAGES)}
    total = sum(counts.values())
    worst = sorted(counts.items(), key=lambda item: -item[1])[:5]
    assert total <= MAX_UNTYPED, f"{total} Any/JSONObject (most: {worst})"


def test_documents_are_read_by_attribute() -> None:
    counts = {name(path): len(STRING_KEY.findall(path.read_text())) for path in sources("agents")}
    total = sum(counts.values())
    worst = sorted(counts.items(), key=lambda item: -item[1])[:5]
    assert total <= MAX_STRING_KEYS, f"{total} string-key reads in agents/ (most: {worst})"


def test_modules_fit_a_sitting() -> None:
    long = {
        name(path): len(path.read_text().splitlines())
        for path in sources(*PACKAGES)
        if name(path) not in LONG_MODULES_ALLOWED
    }
    assert {path: lines for path, lines in long.items() if lines > MAX_MODULE_LINES} == {}


def test_few_functions_pass_a_screenful() -> None:
    long = []
    for path in sources(*PACKAGES):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = (node.end_lineno or node.lineno) - node.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    long.append(f"{name(path)}:{node.lineno} {node.name} ({lines} lines)")
    assert len(long) <= MAX_LONG_FUNCTIONS, long
