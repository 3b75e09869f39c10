"""The tables of environment ids agree with the scene table.

``trailer_env.registry.ENVIRONMENTS`` (from ``trailer_env.scenes.SCENE_ENVS``) is the one
source: the environments page includes the table written from it
(``python -m docs.id_tables``, docs/generated/scenes.md); the package's docstring and
exports and the README's table (which can include nothing) list the ids again for
readers, in the same order, with the episode lengths the cores declare.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import trailer_env
from trailer_env.registry import ENVIRONMENTS
from trailer_env.scenes import SCENE_ENVS

ROOT = Path(__file__).resolve().parents[2]
IDS = list(ENVIRONMENTS)
STEPS = [env.core_class.max_episode_steps for env in ENVIRONMENTS.values()]


def _rows(text: str, pattern: str) -> list[tuple[str, ...]]:
    return [match.groups() for match in re.finditer(pattern, text, flags=re.MULTILINE)]


def test_the_package_docstring_and_exports_list_every_scene() -> None:
    rows = _rows(trailer_env.__doc__ or "", r"^``(trailer_env/[^`]+)``\s+(\d+)\b")
    assert [env_id for env_id, _ in rows] == IDS
    assert [int(steps) for _, steps in rows] == STEPS
    exported = [name for name in trailer_env.__all__ if name.endswith("Env")]
    assert sorted(exported) == sorted(env.__name__ for env in SCENE_ENVS)
    assert all(getattr(trailer_env, env.__name__) is env for env in SCENE_ENVS)


def test_the_readme_table_lists_every_scene() -> None:
    rows = _rows((ROOT / "README.md").read_text(), r"^\| `(trailer_env/[^`]+)` \|")
    assert [env_id for (env_id,) in rows] == IDS


def test_the_environments_page_includes_the_table_written_from_the_scene_table() -> None:
    from docs.id_tables import SCENES_TABLE, scenes_markdown

    table = scenes_markdown()
    assert (ROOT / SCENES_TABLE).read_text() == table, "run python -m docs.id_tables"
    assert f'--8<-- "{SCENES_TABLE}"' in (ROOT / "docs" / "environments.md").read_text()
    rows = _rows(
        table, r"^\| \[`(trailer_env/[^`]+)`\]\(environments/([^)]+)\.md\) \|[^|]+\| (\d+)"
    )
    assert [env_id for env_id, _, _ in rows] == IDS
    assert [page for _, page, _ in rows] == [env_id.split("/")[1].lower() for env_id in IDS]
    assert [int(steps) for _, _, steps in rows] == STEPS
    assert "| 400 (20 s) | survive the episode; ends on a jackknife or the convoy slowed" in table
    assert "| 300 (15 s) | reach the goal; ends on success or a jackknife |" in table


def test_the_table_command_writes_the_file(tmp_path: Path) -> None:
    from docs.id_tables import main, scenes_markdown

    assert main(["--out", str(tmp_path / "scenes.md")]) == 0
    assert (tmp_path / "scenes.md").read_text() == scenes_markdown()
    with pytest.raises(SystemExit) as refused:
        main(["--out", str(tmp_path / "missing" / "scenes.md")])
    assert refused.value.code == 2 and not (tmp_path / "missing").exists()
