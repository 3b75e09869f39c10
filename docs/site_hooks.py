"""MkDocs hooks (``hooks:`` in mkdocs.yml): one page per environment, generated at build time.

For every id of the scene table (:data:`trailer_env.registry.ENVIRONMENTS`, which reads
:data:`trailer_env.scenes.SCENE_ENVS`) the hook writes ``environments/<id>.md`` from the
env class's docstring (Gymnasium's format: Description, Action Space, Observation Space,
Rewards, Starting State, Episode End, Arguments, References), adds the GIFs that
``python -m docs.gifs`` wrote for it (captions from ``docs/img/gifs.json``), turns
"docs/physics.md section N" into a link to that section, and lists the pages under the
nav's "Environments" entry. A new scene gets its page and its nav entry without an edit
here.

It also expands ``<!-- include PATH -->`` (a repository file outside ``docs/``, such as
``benchmarks/README.md`` or ``CONTRIBUTING.md``): its headings one level down, and its
relative links rewritten to work from the page (links to files outside ``docs/`` become
code spans: the site does not publish them).
"""

from __future__ import annotations

import inspect
import json
import re
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

#: The nav entry whose children are the generated environment pages.
NAV_SECTION = "Environments"
#: Folder of the generated pages inside the site.
PAGES = "environments"
IMG = ROOT / "docs" / "img"


def _environments() -> dict[str, type]:
    from trailer_env.registry import ENVIRONMENTS

    return dict(ENVIRONMENTS)


def page_path(env_id: str) -> str:
    """``environments/reverse-v1.md`` for ``trailer_env/Reverse-v1``."""
    return f"{PAGES}/{env_id.split('/')[1].lower()}.md"


def _physics_anchors() -> dict[int, str]:
    anchors = {}
    for line in (ROOT / "docs" / "physics.md").read_text().splitlines():
        match = re.match(r"## (\d+)\.\s+(.*)", line)
        if match:
            slug = re.sub(r"[^\w\s-]", "", line[3:].strip().lower())
            anchors[int(match.group(1))] = re.sub(r"[-\s]+", "-", slug).strip("-")
    return anchors


def link_physics(text: str, anchors: dict[int, str]) -> str:
    """``docs/physics.md section 14`` -> a link to that section of the physics page."""

    def repl(match: re.Match[str]) -> str:
        number = int(match.group(2))
        if number not in anchors:
            return match.group(0)
        return f"[{match.group(0)}](../physics.md#{anchors[number]})"

    pattern = r"`?(?:docs/)?physics\.md`?(,?\s+sections?\s+)(\d+)(?![-\u2013\d])"
    return re.sub(pattern, repl, text)


def _gif_index() -> dict[str, dict[str, Any]]:
    path = IMG / "gifs.json"
    return json.loads(path.read_text()) if path.is_file() else {}


def _caption(entry: dict[str, Any]) -> str:
    seconds = entry["seconds"]
    outcome = {
        "success": f"succeeds after {seconds:.1f} s",
        "failure": f"fails after {seconds:.1f} s",
        "time limit": f"reaches the time limit after {seconds:.1f} s",
        "running": f"the first {seconds:.0f} s, not terminated",
    }.get(entry["outcome"], entry["outcome"])
    policy, n, seed = entry["policy"], entry["n_trailers"], entry["seed"]
    return f"<code>{policy}</code>, n = {n}, test seed {seed}: {outcome}"


def gif_section(env_id: str) -> str:
    """The GIFs of ``env_id`` (committed agent, zero action), or "" if none was written."""
    entries = [
        (name, entry)
        for name, entry in sorted(_gif_index().items())
        if entry["env_id"] == env_id and (IMG / name).is_file()
    ]
    if not entries:
        return ""
    entries.sort(key=lambda item: item[1]["policy"] == "zero")  # the agent first
    figures = []
    for name, entry in entries:
        head = "committed agent" if entry["policy"] != "zero" else "zero action"
        figures.append(
            '<figure markdown="span" style="margin: 0; flex: 0 1 320px">\n'
            f'![{head}: {entry["policy"]} on {env_id}](../img/{name}){{ width="320" }}\n'
            f"<figcaption>{head}: {_caption(entry)}</figcaption>\n"
            "</figure>"
        )
    return (
        '<div style="display: flex; flex-wrap: wrap; gap: 1rem" markdown>\n'
        + "\n".join(figures)
        + "\n</div>\n\n"
        "*The same start under both (one frame every 0.1 s of simulated time, played in "
        "real time; written by `python -m docs.gifs`). Green: far from the singular set; "
        "red: in the singular band or folded.*\n"
    )


def env_page(env_id: str, env_class: type, anchors: dict[int, str]) -> str:
    """The Markdown page of one environment, from its class docstring."""
    doc = inspect.cleandoc(env_class.__doc__ or "")
    summary, _, body = doc.partition("\n")
    core = env_class.core_class  # type: ignore[attr-defined]
    qualified = f"{env_class.__module__}.{env_class.__qualname__}"
    facts = (
        f'`gym.make("{env_id}", n_trailers=n)` · class '
        f"[`{env_class.__qualname__}`][{qualified}] · "
        f"`max_episode_steps = {core.max_episode_steps}`"
    )
    gifs = gif_section(env_id)
    parts = [f"# {env_id}", summary.strip(), facts]
    if gifs:
        parts.append(gifs)
    parts.append(link_physics(body.strip(), anchors))
    parts.append(
        f"*This page is generated at build time from the class docstring (`help({qualified})`).*"
    )
    return "\n\n".join(parts) + "\n"


_INCLUDE = re.compile(r"^<!-- include (?P<path>[\w./-]+) -->$", re.M)
_LINK = re.compile(r"(?P<bang>!?)\[(?P<text>[^\]]*)\]\((?P<target>[^)\s]+)\)")


def include(path: str, page_dir: Path, demote: bool = True) -> str:
    """A repository file's Markdown as it reads from a page in ``page_dir``."""
    source = ROOT / path
    text = source.read_text()
    docs = ROOT / "docs"

    def relink(match: re.Match[str]) -> str:
        target = match.group("target")
        if re.match(r"[a-z]+:|#", target):
            return match.group(0)
        file_part, _, anchor = target.partition("#")
        resolved = (source.parent / file_part).resolve()
        if resolved == source.resolve():
            return match.group(0)
        if docs in resolved.parents:
            new = Path(_relpath(resolved, page_dir)).as_posix() + (f"#{anchor}" if anchor else "")
            return f"{match.group('bang')}[{match.group('text')}]({new})"
        shown = resolved.relative_to(ROOT).as_posix() if ROOT in resolved.parents else target
        return f"{match.group('text')} (`{shown}`)" if match.group("text") else f"`{shown}`"

    out, fence = [], False
    for line in text.splitlines():
        if line.lstrip().startswith("```"):
            fence = not fence
        if not fence:
            if demote and line.startswith("#"):
                line = "#" + line
            line = _LINK.sub(relink, line)
        out.append(line)
    return "\n".join(out) + "\n"


def _relpath(target: Path, start: Path) -> str:
    import os

    return os.path.relpath(target, start)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    """Expand ``<!-- include PATH -->`` lines."""
    page_dir = (ROOT / "docs" / page.file.src_uri).parent

    def expand(match: re.Match[str]) -> str:
        return include(match.group("path"), page_dir, demote=page.file.src_uri != "contributing.md")

    return _INCLUDE.sub(expand, markdown)


def on_config(config: Any) -> Any:
    """List the generated pages under the nav's "Environments" entry."""
    nav = config.get("nav") or []
    pages = [{env_id: page_path(env_id)} for env_id in _environments()]
    for item in nav:
        if isinstance(item, dict) and NAV_SECTION in item:
            children = item[NAV_SECTION]
            if not isinstance(children, list):
                children = [children]
            item[NAV_SECTION] = [*children, *pages]
            break
    else:
        nav.append({NAV_SECTION: pages})
    return config


def on_files(files: Any, config: Any) -> Any:
    """Add one generated page per environment."""
    from mkdocs.structure.files import File

    anchors = _physics_anchors()
    for env_id, env_class in _environments().items():
        content = env_page(env_id, env_class, anchors)
        files.append(File.generated(config, page_path(env_id), content=content))
    return files
