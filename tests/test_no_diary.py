"""No tracked file reads as a lab diary.

The project speaks of the project: what holds now and the command that shows it. History
goes to CHANGELOG.md by version. So no tracked text file names a working session by
number or by position ("the previous one"), a throw-away script, the run folders of past
experiments (``runs/`` followed by a session tag and a number), a host by its place in
time, or a machine's private scratch folder.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: Each pattern names one kind of diary phrase. Words that merely share a spelling stay
#: legal: a desktop or Ray session, pytest's ``scope="session"``, training "from
#: scratch", a temporary folder named ``scratch``.
DIARY = {
    "a numbered session": re.compile(
        r"\bsessions?(?:[\s-]+(?:up\s+to|of|before|since))?[\s-]*\d", re.I
    ),
    "a session by its place in time": re.compile(
        r"\b(?:this|that|an\s+earlier|earlier|a\s+later|later|the\s+previous|previous|"
        r"the\s+first|the\s+next|the\s+last|each|every|one|two|three|several|past)\s+sessions?\b",
        re.I,
    ),
    "a throw-away script": re.compile(r"\bscratch[\s_-]+scripts?\b", re.I),
    "a diary run folder": re.compile(r"\bruns/(?:s|rl)\d+\b", re.I),
    "a machine's scratch folder": re.compile(r"/work/scr" r"atch\b", re.I),
    "a host by its place in time": re.compile(
        r"\b(?:this|that|an\s+earlier|earlier|the\s+earlier|an\s+older|older|"
        r"earlier,\s+slower|(?:the|a)\s+slower|(?:the|a)\s+faster|the\s+previous|"
        r"previous)\s+hosts?\b|\bhosts?\s+of\s+(?:the\s+)?(?:earlier|previous)\b|"
        r"\bthe\s+host\s+that\s+first\b",
        re.I,
    ),
    "an audit": re.compile(r"\b(?:found|seen|shown)\s+by\s+the\s+audit\b|\bthe\s+audit\b", re.I),
}


def diary_phrases(text: str) -> list[tuple[int, str, str]]:
    """The diary phrases of ``text``: (line number, kind, the phrase), in reading order."""
    found: list[tuple[int, str, str]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        for kind, pattern in DIARY.items():
            found.extend((number, kind, match.group(0)) for match in pattern.finditer(line))
    return found


def _tracked_files() -> list[Path]:
    try:
        listing = subprocess.run(
            ["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True
        ).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout: the tracked files are unknown")
    names = [name for name in listing.decode().split("\0") if name]
    return [ROOT / name for name in names if (ROOT / name).is_file()]


def _text(path: Path) -> str | None:
    """The file's text, or None for a binary file (a NUL byte, or not UTF-8)."""
    data = path.read_bytes()
    if b"\0" in data[:8192]:
        return None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return None


def test_the_detector_finds_each_kind_and_passes_the_ordinary_words() -> None:
    # Built by parts, so this file holds no phrase of its own.
    word = "sess" + "ion"
    diary = [
        f"measured in {word} 14",
        f"the {word}-17 host",
        f"on the hosts of {word}s up to 16",
        f"re-run in this {word}",
        f"an earlier {word}'s table",
        "a scr" + "atch script, not shipped",
        "python -m agents.train --run-dir " + "runs/" + "s25/n3full_s0",
        "runs/" + "rl29/ppo_v1_n2_s0",
        "/work/" + "scratch/dagger/floor_n1_s0",
        "(26 on an earlier, slower " + "host at load 3)",
        "38-40 on the slower " + "host",
        "found by the " + "audit",
    ]
    kinds = [diary_phrases(line) for line in diary]
    assert [len(found) >= 1 for found in kinds] == [True] * len(diary)
    ordinary = [
        f'@pytest.fixture(autouse=True, scope="{word}")',
        f"without a desktop {word} SDL prints a warning",
        f"the local Ray {word}'s logs are copied to the run folder",
        "PPO from scratch keeps 0-3 %",
        "with tempfile.TemporaryDirectory() as scratch:",
        "runs/reverse_v1_n3_ppo_s0 and runs/sac_v1_n1_s0",
        "every CPU gives the same headline rates",
        "Ray starts workers on the other hosts of the cluster",
    ]
    assert [diary_phrases(line) for line in ordinary] == [[] for _ in ordinary]
    assert diary_phrases(f"line one\nsee {word} 3 and " + "runs/" + "s3/x") == [
        (2, "a numbered session", f"{word} 3"),
        (2, "a diary run folder", "runs/" + "s3"),
    ]


def test_no_tracked_file_reads_as_a_diary() -> None:
    files = _tracked_files()
    assert len(files) > 100, "the checkout lists its tracked files"
    hits = []
    for path in files:
        text = _text(path)
        if text is None:
            continue
        for number, kind, phrase in diary_phrases(text):
            hits.append(f"{path.relative_to(ROOT)}:{number}: {kind}: {phrase!r}")
    assert not hits, (
        f"{len(hits)} diary phrases (say what holds now and the command that shows it, "
        "or move the history to CHANGELOG.md):\n" + "\n".join(hits)
    )
