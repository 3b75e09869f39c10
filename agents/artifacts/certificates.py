"""Certificate files: names, statuses, the committed ones, writing."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np

#: Committed certificates: ``certificate.json`` of the commands in docs/physics.md
#: section 14 (the per-start statuses; the action records are rebuilt by the command).
CERTIFICATES_DIR = Path(__file__).resolve().parent.parent / "certificates"


FEASIBLE = "feasible"


NOT_RECOVERABLE = "not recoverable"


OPEN = "open"


def write_certificate(certificate: dict[str, Any], out: Path, overwrite: bool) -> None:
    """Write certificate.json, certificate.md and actions/seed_<seed>.npy under ``out``.

    Raises:
        FileExistsError: If ``out`` exists and ``overwrite`` is False.
    """
    if out.exists():
        if not overwrite:
            raise FileExistsError(f"{out} exists; pass --overwrite to replace it")
        shutil.rmtree(out)
    (out / "actions").mkdir(parents=True)
    document = {key: value for key, value in certificate.items() if key != "actions"}
    for start in document["starts"]:
        if start["status"] == FEASIBLE:
            start["actions_file"] = f"actions/seed_{start['seed']}.npy"
    (out / "certificate.json").write_text(json.dumps(document, indent=2) + "\n")
    (out / "certificate.md").write_text(markdown(certificate))
    for seed, sequence in certificate["actions"].items():
        np.save(out / "actions" / f"seed_{seed}.npy", sequence, allow_pickle=False)


def certificate_path(env_id: str, n_trailers: int, directory: Path = CERTIFICATES_DIR) -> Path:
    """Where the committed certificate of a scene and n lives: ``<scene>_n<n>.json``."""
    from agents.envs import scene_of

    return directory / f"{scene_of(env_id)}_n{n_trailers}.json"


def committed_certificate(
    env_id: str, n_trailers: int, directory: Path = CERTIFICATES_DIR
) -> dict[str, Any] | None:
    """The committed certificate of ``env_id`` with ``n_trailers``, or None.

    Raises:
        ValueError: If the file is not a certificate of that scene and n.
    """
    path = certificate_path(env_id, n_trailers, directory)
    if not path.is_file():
        return None
    try:
        document = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ValueError(f"{path} is not JSON: {error}") from None
    if (
        not isinstance(document, dict)
        or document.get("env_id") != env_id
        or document.get("env_kwargs", {}).get("n_trailers") != n_trailers
        or not isinstance(document.get("starts"), list)
    ):
        raise ValueError(f"{path} is not a certificate of {env_id} with n = {n_trailers}")
    return document


def markdown(certificate: dict[str, Any]) -> str:
    """The certificate's summary and per-start table in Markdown."""
    count = certificate["episodes"]
    lines = [
        f"# {certificate['env_id']}, n = {certificate['env_kwargs']['n_trailers']}, "
        f"seeds {certificate['seeds'][0]}-{certificate['seeds'][1]}",
        "",
        f"ceiling (feasible, replayed): {certificate['feasible']}/{count} = "
        f"{100 * certificate['ceiling']:.0f}%; not recoverable (screen): "
        f"{certificate['not_recoverable']}; open: {certificate['open']}",
        f"planner: {certificate['planner']['first_pass_safe']}/{count} safe in one pass "
        f"({certificate['planner']['first_pass_wall_time_s']} s), "
        f"{certificate['planner']['wall_time_s']} s with up to "
        f"{certificate['planner']['restarts']} restarts; "
        f"screen: {certificate['screen']['wall_time_s']} s",
        "",
        "| seed | status | screen stroke / s_max | planner steps |",
        "|---|---|---|---|",
    ]
    for start in certificate["starts"]:
        fraction = start["screen_stroke_fraction"]
        stroke = "inf" if fraction is None else f"{fraction:.2f}"
        lines.append(
            f"| {start['seed']} | {start['status']} | {stroke} | {start['planner_length']} |"
        )
    return "\n".join(lines) + "\n"
