"""One compact table from several evaluations (the program: :mod:`agents.commands.compare`).

Each evaluation is an ``agents.evaluate`` output folder (its ``results.json``, read and
checked whole) under a column label; folders under one label share the column (e.g. the
same starts played by policies that need different env keywords). A row per policy, in
the order first met; a cell is the scene's headline rate in % (``-``: not played there).
Under the table, each folder's scene, env keywords, episodes and seeds.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from agents.artifacts.results import ResultsDocument, read_results
from agents.envs import headline_metric

RESULTS = "results.json"


def read_evaluation(folder: Path) -> ResultsDocument:
    """The one results document of ``agents.evaluate``'s output ``folder``.

    Raises:
        ValueError: If the folder has no readable ``results.json`` or it holds a list
            (``agents.report``'s) rather than one evaluation.
    """
    path = folder / RESULTS
    if not path.is_file():
        raise ValueError(f"{folder} has no {RESULTS} (an agents.evaluate output folder)")
    documents = read_results(path)
    if len(documents) != 1:
        raise ValueError(f"{path} holds {len(documents)} evaluations; give one per folder")
    return documents[0]


def markdown(columns: Sequence[tuple[str, Path, ResultsDocument]]) -> str:
    """The table of ``columns`` (label, folder, its document), see the module.

    Raises:
        ValueError: If one policy is in two folders of one label, or the folders' scenes
            differ.
    """
    scenes = {document.env_id for _, _, document in columns}
    if len(scenes) != 1:
        raise ValueError(f"the evaluations are of different scenes: {sorted(scenes)}")
    metric = headline_metric(scenes.pop())
    labels = list(dict.fromkeys(label for label, _, _ in columns))
    cells: dict[str, dict[str, str]] = {}
    for label, _, document in columns:
        for policy in document.policies:
            row = cells.setdefault(policy.name, {})
            if label in row:
                raise ValueError(f"{policy.name} is in two evaluations under {label!r}")
            row[label] = f"{100 * getattr(policy.summary, metric):.0f}"
    name = metric.removesuffix("_rate")
    lines = [
        f"| policy | {' | '.join(labels)} |",
        "|---|" + "---|" * len(labels),
        *(
            f"| {policy} | {' | '.join(row.get(label, '-') for label in labels)} |"
            for policy, row in cells.items()
        ),
        "",
        f"Each cell: {name} %. The evaluations:",
        "",
    ]
    for label, folder, document in columns:
        first, last = document.seeds
        settings = ", ".join(f"{key}={value}" for key, value in document.env_kwargs.items())
        lines.append(
            f"- {label}: `{folder.name}`, {document.env_id.split('/')[-1]} ({settings}), "
            f"{document.episodes} episodes, seeds {first}-{last}"
        )
    return "\n".join(lines) + "\n"
