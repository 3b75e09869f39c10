"""The results pages: a picture first, tables written by commands, no figure typed by hand.

The hand-written part of a results page (what is left once the front matter, the code
blocks and the included generated files are taken out) may hold numbers only where each
is one that the generated files it includes also hold: a figure is never typed by hand.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
#: The results pages and the generated files they include.
RESULTS_PAGES = ("results.md", "from_reward.md")
NUMBER = re.compile(r"(?<![\w.])\d+(?:\.\d+)?(?![\w])")
INCLUDE = re.compile(r'^--8<-- "([^"]+)"$', flags=re.M)


def hand_written(text: str) -> str:
    """``text`` without its front matter, its code blocks and its include lines."""
    text = re.sub(r"\A---\n.*?\n---\n", "", text, flags=re.S)
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    return INCLUDE.sub("", text)


def included(text: str) -> str:
    return "\n".join((ROOT / path).read_text() for path in INCLUDE.findall(text))


def test_the_detector_finds_typed_figures() -> None:
    assert NUMBER.findall(hand_written("a 97.5 % rate, n = 2, Reverse-v1\n```\n42\n```")) == [
        "97.5",
        "2",
    ]


@pytest.mark.parametrize("page", RESULTS_PAGES)
def test_every_number_in_the_hand_written_part_is_in_the_generated_files(page: str) -> None:
    text = (DOCS / page).read_text()
    generated = included(text)
    assert generated, f"{page} includes no generated file"
    known = set(NUMBER.findall(generated))
    typed = sorted(set(NUMBER.findall(hand_written(text))) - known)
    assert not typed, f"docs/{page}: numbers typed by hand: {typed}"


@pytest.mark.parametrize("page", RESULTS_PAGES)
def test_a_results_page_opens_with_a_picture(page: str) -> None:
    body = hand_written((DOCS / page).read_text()).lstrip()
    title, _, rest = body.partition("\n")
    assert title.startswith("# ")
    first = next(block for block in rest.split("\n\n") if block.strip())
    assert first.strip().startswith("!["), f"docs/{page} opens with {first[:60]!r}"


def test_every_scenario_table_has_its_picture_above_it() -> None:
    tables = (DOCS / "generated" / "results_tables.md").read_text()
    sections = re.split(r"^#### ", tables, flags=re.M)[1:]
    scenarios = [section for section in sections if "n = " in section.partition("\n")[0]]
    assert len(scenarios) >= 10
    for section in scenarios:
        picture = re.search(r"!\[[^\]]*\]\((img/results/[\w]+\.png)\)", section)
        assert picture, f"no picture above {section.partition(chr(10))[0]}"
        assert section.index(picture.group(0)) < section.index("| policy |")
        assert (DOCS / picture.group(1)).is_file(), picture.group(1)
        assert "python -m agents.reproduce" in section or "made by" in section
