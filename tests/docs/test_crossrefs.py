"""Every cross-reference to a section of docs/physics.md points at an existing section.

A reference is any of

* ``physics.md section 9``, ``physics.md sections 3, 4 and 9``, ``physics.md sections 5-8``,
  ``physics.md s. 9``, ``physics.md §12``, ``physics.md, section 14``,
  ``[docs/physics.md](docs/physics.md), section 14`` (line breaks and comment markers
  between the words allowed);
* ``section 14 of docs/physics.md``, ``§12 of physics.md``;
* a link or path with an anchor, ``docs/physics.md#12-how-the-tests-verify-it`` (the
  anchor must be the slug of a heading, as MkDocs and GitHub write it);
* ``physics.md ("Sizing the actuator")``: a title without a number, which must be a
  heading of physics.md or the bold run-in title of one of its paragraphs;
* inside physics.md itself, ``section 9`` / ``sections 4 and 5`` (the thesis's dotted
  numbers, ``section 3.2.2``, are the thesis's and are skipped).

Where a numbered reference carries a quoted title right after it (``section 9 ("Steering
with a moving mass")``), the title must match that section: its heading or the bold
run-in title of one of its paragraphs. Every .py and .md file of the repository is
scanned; nothing is tolerated.
"""

from __future__ import annotations

import re
import subprocess
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PHYSICS = ROOT / "docs" / "physics.md"

# Between two words of a reference: white space, and the comment markers and quote
# characters a wrapped docstring, comment or Markdown line puts there.
_GAP = r"(?:[\s*>`]|#:?)+"
_NUMBER = r"\d+(?![.\d]*\.\d)(?!\d)"  # 9, not the thesis's 3.2.2
_NUMBERS = rf"{_NUMBER}(?:(?:{_GAP})?(?:,|-|\u2013|to|and|&)(?:{_GAP})?{_NUMBER})*"
_SECTION_WORD = r"(?:sections?|sec\.|s\.|§§?)"
_PHYSICS = r"(?:docs/)?physics(?:\.md)?"
_TITLE = r"""(?P<title_gap>[\s,(:]*)(?:"(?P<title>[^"\n]+)"|“(?P<title2>[^”\n]+)”)"""

# physics.md section 9 / physics.md, sections 3, 4 and 9 / [x](docs/physics.md), section 14
_AFTER = re.compile(
    rf"(?<![\w/])(?:docs/)?physics\.md(?:\)|`)?,?(?:{_GAP})?\(?{_SECTION_WORD}(?:{_GAP})?"
    rf"(?P<numbers>{_NUMBERS})(?:{_TITLE})?",
    re.IGNORECASE,
)
# section 14 of docs/physics.md
_BEFORE = re.compile(
    rf"{_SECTION_WORD}(?:{_GAP})?(?P<numbers>{_NUMBERS}){_GAP}of{_GAP}(?:the{_GAP})?"
    rf"`?\[?{_PHYSICS}\b",
    re.IGNORECASE,
)
# physics.md#12-how-the-tests-verify-it
_ANCHOR = re.compile(r"physics\.md#(?P<anchor>[A-Za-z0-9_\-]+)")
# physics.md ("Sizing the actuator")
_TITLE_ONLY = re.compile(
    rf"physics\.md`?(?:{_GAP})?\((?:\"(?P<title>[^\"\n]+)\"|“(?P<title2>[^”\n]+)”)\)"
)
# inside physics.md, or a file that names it: section 9, sections 4 and 5, Section 12
# (not the thesis's: "thesis section 3.4", "the thesis's section 2")
_BARE = re.compile(
    rf"(?<![\w.])(?<!thesis )(?<!thesis's )sections?{_GAP}(?P<numbers>{_NUMBERS})(?![\w.]*\.\d)"
    rf"(?!{_GAP}of{_GAP}(?:the{_GAP})?`?\[?{_PHYSICS}\b)(?:{_TITLE})?",
    re.IGNORECASE,
)


@dataclass(frozen=True)
class Section:
    number: int
    title: str
    anchor: str
    run_in_titles: tuple[str, ...]


@dataclass(frozen=True)
class Reference:
    path: str
    line: int
    text: str
    numbers: tuple[int, ...] = ()
    title: str | None = None
    anchor: str | None = None


def slugify(heading: str) -> str:
    """The anchor MkDocs' toc extension (and GitHub) give a heading."""
    slug = re.sub(r"[^\w\s-]", "", heading.strip().lower())
    return re.sub(r"[-\s]+", "-", slug).strip("-")


def physics_sections(text: str | None = None) -> dict[int, Section]:
    """The numbered sections of docs/physics.md with their bold run-in paragraph titles."""
    text = PHYSICS.read_text() if text is None else text
    sections: dict[int, Section] = {}
    parts = re.split(r"^## ", text, flags=re.M)
    for part in parts[1:]:
        heading, _, body = part.partition("\n")
        match = re.match(r"(\d+)\.\s+(.*)", heading.strip())
        if not match:
            continue
        run_in = tuple(
            m.strip().rstrip(".").strip()
            for m in re.findall(r"^\*\*([^*\n]+)\*\*", body, flags=re.M)
        )
        number = int(match.group(1))
        sections[number] = Section(number, match.group(2).strip(), slugify(heading), run_in)
    return sections


def _expand(numbers: str) -> tuple[int, ...]:
    out: list[int] = []
    tokens = re.findall("\\d+|-|\u2013|to\\b", numbers)
    i = 0
    while i < len(tokens):
        if tokens[i] in {"-", "\u2013", "to"} and out and i + 1 < len(tokens):
            out.extend(range(out[-1] + 1, int(tokens[i + 1]) + 1))
            i += 2
            continue
        if tokens[i].isdigit():
            out.append(int(tokens[i]))
        i += 1
    return tuple(out)


def _title(match: re.Match[str]) -> str | None:
    groups = match.groupdict()
    return groups.get("title") or groups.get("title2")


def references_in(path: Path, text: str) -> list[Reference]:
    """The references to physics.md's sections in one file."""
    rel = path.relative_to(ROOT).as_posix()
    refs: list[Reference] = []

    def line_of(pos: int) -> int:
        return text.count("\n", 0, pos) + 1

    def add(match: re.Match[str], **kwargs: object) -> None:
        snippet = " ".join(match.group(0).split())
        refs.append(Reference(rel, line_of(match.start()), snippet, **kwargs))  # type: ignore[arg-type]

    spans: list[tuple[int, int]] = []
    for pattern in (_AFTER, _BEFORE):
        for match in pattern.finditer(text):
            add(match, numbers=_expand(match.group("numbers")), title=_title(match))
            spans.append(match.span())
    for match in _ANCHOR.finditer(text):
        add(match, anchor=match.group("anchor"))
    for match in _TITLE_ONLY.finditer(text):
        add(match, title=_title(match))
    if path == PHYSICS or "physics.md" in text:
        for match in _BARE.finditer(text):
            if any(start <= match.start() < end for start, end in spans):
                continue
            add(match, numbers=_expand(match.group("numbers")), title=_title(match))
    return refs


def repository_files() -> list[Path]:
    """The repository's .py and .md files (git's view when available)."""
    try:
        listed = subprocess.run(
            ["git", "ls-files", "--cached", "--others", "--exclude-standard", "*.py", "*.md"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.split()
        files = [ROOT / name for name in listed]
    except (OSError, subprocess.CalledProcessError):
        skip = {".venv", "site", "build", "node_modules", ".git"}
        files = [
            p
            for p in ROOT.rglob("*")
            if p.suffix in {".py", ".md"} and not skip & set(p.relative_to(ROOT).parts)
        ]
    this = Path(__file__).resolve()  # its docstring and samples cite sections on purpose
    return sorted(p for p in files if p.is_file() and p.resolve() != this)


def _norm(title: str) -> str:
    return " ".join(re.sub(r"[^\w\s]", " ", title.lower()).split())


def _title_fits(title: str, section: Section) -> bool:
    wanted = _norm(title)
    candidates = (section.title, *section.run_in_titles)
    return any(wanted and wanted in _norm(c) for c in candidates)


def problems(refs: list[Reference], sections: dict[int, Section]) -> list[str]:
    """Human-readable descriptions of the references that do not resolve."""
    anchors = {s.anchor for s in sections.values()}
    out = []
    for ref in refs:
        where = f"{ref.path}:{ref.line}: {ref.text!r}"
        missing = [n for n in ref.numbers if n not in sections]
        if missing:
            out.append(f"{where}: no section {missing} in docs/physics.md")
            continue
        if ref.anchor is not None and ref.anchor not in anchors:
            out.append(f"{where}: no heading with anchor #{ref.anchor}")
            continue
        if ref.title is not None:
            if ref.numbers:
                if not any(_title_fits(ref.title, sections[n]) for n in ref.numbers):
                    titles = "; ".join(f"{n}. {sections[n].title}" for n in ref.numbers)
                    out.append(f"{where}: title {ref.title!r} is not that of {titles}")
            elif not any(_title_fits(ref.title, s) for s in sections.values()):
                out.append(f"{where}: no section or paragraph titled {ref.title!r}")
    return out


def all_references() -> list[Reference]:
    refs: list[Reference] = []
    for path in repository_files():
        refs.extend(references_in(path, path.read_text(encoding="utf-8", errors="replace")))
    return refs


def test_the_parser_reads_physics_md_and_every_form_of_reference() -> None:
    sections = physics_sections()
    assert sorted(sections) == list(range(1, len(sections) + 1)) and len(sections) >= 14
    assert sections[12].anchor == "12-how-the-tests-verify-it"
    sample = (
        'x physics.md section 9 ("Steering with a moving mass") y\n'
        "see docs/physics.md sections 3, 4\n    # and 9 here\n"
        "(docs/physics.md\n    section 14) and [p](docs/physics.md), section 2\n"
        "section 10 of docs/physics.md; physics.md s. 7; physics.md §12; physics.md sections 5-8\n"
        "[t](docs/physics.md#12-how-the-tests-verify-it) "
        'docs/physics.md ("Sizing the actuator")\n'
        'physics.md section 99, physics.md section 7 ("Steering with a moving mass")\n'
    )
    refs = references_in(ROOT / "sample.md", sample)
    got = sorted(((r.line, r.numbers, r.title, r.anchor) for r in refs), key=str)
    assert got == sorted(
        [
            (1, (9,), "Steering with a moving mass", None),
            (2, (3, 4, 9), None, None),
            (4, (14,), None, None),
            (5, (2,), None, None),
            (6, (10,), None, None),
            (6, (7,), None, None),
            (6, (12,), None, None),
            (6, (5, 6, 7, 8), None, None),
            (7, (), None, "12-how-the-tests-verify-it"),
            (7, (), "Sizing the actuator", None),
            (8, (99,), None, None),
            (8, (7,), "Steering with a moving mass", None),
        ],
        key=str,
    ), got
    bad = problems(refs, sections)
    assert len(bad) == 2 and "99" in bad[0] and "not that of 7." in bad[1], bad


def test_every_reference_to_a_physics_section_resolves() -> None:
    sections = physics_sections()
    refs = all_references()
    assert len(refs) > 40, "the scan finds the repository's references"
    bad = problems(refs, sections)
    assert not bad, "references to docs/physics.md that do not resolve:\n" + "\n".join(bad)
