"""docs/generated/README.md names every file and folder of docs/generated, and only those.

Everything in docs/generated is written by a command and shown by a page; the index says
which page and which command. A file left there that the index does not name is a
leftover (a past experiment's run folder, say), and a name in the index that is gone is
a stale line.
"""

from __future__ import annotations

import fnmatch
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
GENERATED = ROOT / "docs" / "generated"
INDEX = GENERATED / "README.md"


def _tracked_entries() -> set[str]:
    """The top-level names under docs/generated that git tracks (folders end in /)."""
    try:
        listing = subprocess.run(
            ["git", "ls-files", "-z", "docs/generated"],
            cwd=ROOT,
            capture_output=True,
            check=True,
        ).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout: the tracked files are unknown")
    entries = set()
    for name in filter(None, listing.decode().split("\0")):
        if not (ROOT / name).exists():
            continue  # deleted in the working tree
        parts = Path(name).relative_to("docs/generated").parts
        entries.add(parts[0] + "/" if len(parts) > 1 else parts[0])
    return entries - {"README.md"}


def _table_names() -> list[str]:
    """The names in the first column of the index's table (`a`, `b/`, `rl_curves_*/`),
    not those in parentheses (the files a folder holds)."""
    names = []
    for line in INDEX.read_text().splitlines():
        cells = line.split("|")
        if len(cells) > 2 and not set(cells[1].strip()) <= set("-"):
            names += re.findall(r"`([^`]+)`", re.sub(r"\([^)]*\)", "", cells[1]))
    return names


def test_the_index_names_every_generated_entry_and_each_exists() -> None:
    entries = _tracked_entries()
    names = _table_names()
    assert len(entries) >= 10 and len(names) >= 10
    unnamed = sorted(e for e in entries if not any(fnmatch.fnmatch(e, n) for n in names))
    assert not unnamed, f"docs/generated/README.md does not name {unnamed}"
    stale = sorted(n for n in names if not any(fnmatch.fnmatch(e, n) for e in entries))
    assert not stale, f"docs/generated/README.md names {stale}, which are not there"


def test_every_chart_folder_has_its_command() -> None:
    text = INDEX.read_text()
    charts = sorted(e.rstrip("/") for e in _tracked_entries() if e.startswith("rl_curves_"))
    assert len(charts) >= 20
    drawn = set(re.findall(r"--out docs/generated/(rl_curves_\w+)", text))
    missing = [chart for chart in charts if chart not in drawn]
    assert not missing, f"no command in docs/generated/README.md draws {missing}"
