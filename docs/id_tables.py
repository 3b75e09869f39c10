"""The environments page's table of ids, written from the scene table.

Run from the repository root::

    python -m docs.id_tables [--out docs/generated/scenes.md]

One row per registered id (:data:`trailer_env.registry.ENVIRONMENTS`, in its order): the
id linked to the scene's generated page (:func:`docs.site_hooks.page_path`), its task (the
first line of the env class's docstring), its episode length in steps and seconds (the
default control period) and how an episode succeeds and ends (the core's ``objective``
and ``failure_words``). ``docs/environments.md`` includes the file;
``tests/docs/test_id_tables.py`` checks that the committed file is this table.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from agents.envs import HEADLINE_ENV_ID
from docs.site_hooks import page_path
from trailer_env.benchmark import write_atomic
from trailer_env.core import ConvoyCore
from trailer_env.objective import Objective
from trailer_env.registry import ENVIRONMENTS
from trailer_env.settings import settings_from_kwargs

#: Where the table is written and the page includes it from.
SCENES_TABLE = Path("docs") / "generated" / "scenes.md"


def _task(env_class: type) -> str:
    lines = (env_class.__doc__ or "").strip().splitlines()
    task = lines[0].rstrip(".").replace("``", "`") if lines else ""
    return task[:1].lower() + task[1:]


def _either(items: list[str]) -> str:
    """``"a, b or c"``."""
    return " or ".join(filter(None, (", ".join(items[:-1]), items[-1])))


def _end(core_class: type[ConvoyCore]) -> str:
    """How an episode of the scene succeeds and what ends it."""
    failures = ["a jackknife", *filter(None, [core_class.failure_words])]
    if core_class.objective is Objective.SURVIVAL:
        return f"survive the episode; ends on {_either(failures)}"
    return f"reach the goal; ends on {_either(['success', *failures])}"


def scenes_markdown() -> str:
    """The table (Markdown) of every registered id."""
    dt = settings_from_kwargs().dt
    rows = [
        "| id | task | steps | success / end |",
        "|---|---|---|---|",
    ]
    for env_id, env_class in ENVIRONMENTS.items():
        core = env_class.core_class
        steps = core.max_episode_steps
        headline = "**the headline task**: " if env_id == HEADLINE_ENV_ID else ""
        rows.append(
            f"| [`{env_id}`]({page_path(env_id)}) | {headline}{_task(env_class)} "
            f"| {steps} ({steps * dt:g} s) | {_end(core)} |"
        )
    return "\n".join(rows) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Write the table; a folder that does not exist exits 2 naming ``--out``."""
    parser = argparse.ArgumentParser(
        prog="python -m docs.id_tables", description=(__doc__ or "").split("\n")[0]
    )
    parser.add_argument("--out", type=Path, default=SCENES_TABLE, help="the Markdown file")
    args = parser.parse_args(argv)
    if not args.out.parent.is_dir():
        parser.error(f"argument --out: no folder {args.out.parent}")
    write_atomic(args.out, scenes_markdown())
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
