"""Pages read in one sitting: the README is a product page, no hand-written page is a book."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: The README: at most this many lines and words (code blocks and tables included).
README_LINES, README_WORDS = 150, 1200
#: Any hand-written page of the site (docs/generated is written by commands).
PAGE_LINES = 700


def test_the_readme_is_a_product_page() -> None:
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= README_LINES
    assert len(text.split()) <= README_WORDS
    first_screen = "\n".join(text.splitlines()[:30])
    assert re.search(r"^!\[[^\]]+\]\(docs/img/[^)]+\.(gif|png)\)$", first_screen, flags=re.M)
    assert "bash scripts/demo.sh" in first_screen
    assert "bash scripts/test.sh" in first_screen


def test_no_hand_written_page_is_over_the_limit() -> None:
    pages = [
        path
        for path in [*(ROOT / "docs").rglob("*.md"), ROOT / "CONTRIBUTING.md"]
        if "generated" not in path.relative_to(ROOT).parts
    ]
    long = {
        str(path.relative_to(ROOT)): count
        for path in pages
        if (count := len(path.read_text().splitlines())) > PAGE_LINES
    }
    assert len(pages) > 15
    assert not long, f"pages over {PAGE_LINES} lines: {long}"
