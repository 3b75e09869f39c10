"""Certify a scene's ceiling: which test starts some controller can keep safe.

Usage::

    python -m agents.certify --env trailer_env/Reverse-v1 --n-trailers 2 \\
        --seeds 1000-1099 --out out/certify/reverse-v1-n2 [--overwrite]

For every seed it runs the feasibility screen (:mod:`agents.screen`, a linear
programme on the linearised convoy) and the planner (:mod:`agents.planner`, on the
real nonlinear model, all starts in one batch; the starts it did not keep safe are
planned again with new planner seeds, ``--restarts`` times at most), then replays the
planner's action sequence open-loop in a fresh single env (``gym.make``, ``reset(seed=seed)``). Each
start is then:

* ``feasible``: the replay was safe (never folded, never left the task, never in the
  singular band) for the full episode; the sequence is written as
  ``actions/seed_<seed>.npy`` (float64, one action per step: feasibility is a
  closed-loop property and its record must be the exact trace; open-loop over 20 s
  the unstable convoy amplifies a float32 rounding by about e^20);
* ``not recoverable``: the screen found no recovery within the rail's stroke (a
  statement about the linearisation);
* ``open``: neither.

The ceiling is the feasible fraction (a lower bound on what any controller can reach;
``1 - not recoverable`` is the screen's upper estimate). Writes ``certificate.json``
(per start: seed, status, screen stroke fraction, planner length) and
``certificate.md``. An existing ``--out`` is refused unless ``--overwrite``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from agents.envs import ENV_IDS, check_env_id, env_settings
from agents.planner import PlannerConfig, SamplingPlanner, plan_episodes
from agents.screen import DEFAULT_HORIZON, screen_start
from trailer_env.registry import core_class_of
from trailer_env.vector import seed_generators

#: Committed certificates: ``certificate.json`` of the commands in docs/physics.md
#: section 14 (the per-start statuses; the action records are rebuilt by the command).
CERTIFICATES_DIR = Path(__file__).resolve().parent / "certificates"

#: Default number of planner restarts on the starts a pass did not keep safe.
DEFAULT_RESTARTS = 3

FEASIBLE = "feasible"
NOT_RECOVERABLE = "not recoverable"
OPEN = "open"


@dataclass(frozen=True)
class Replay:
    """An open-loop replay's outcome in a fresh env."""

    safe: bool
    length: int


def replay(env_id: str, env_kwargs: dict[str, Any], seed: int, actions: np.ndarray) -> Replay:
    """Play ``actions`` (steps,) or (steps, action_dim) open-loop from ``reset(seed=seed)``.

    Safe: never in the singular band, not terminated as a failure, and every action
    played (the episode reached the truncation or ran out of actions).
    """
    env = gym.make(env_id, **env_kwargs)
    env.reset(seed=seed)
    sequence = np.asarray(actions, dtype=np.float64).reshape(len(actions), -1)
    length = 0
    safe = True
    for action in sequence:
        _, _, terminated, truncated, info = env.step(action)
        length += 1
        if info["cost"] > 0.0 or (terminated and not info["is_success"]):
            safe = False
            break
        if terminated or truncated:
            break
    env.close()
    return Replay(safe, length)


def parse_seeds(text: str) -> list[int]:
    """ "1000-1099" -> [1000, ..., 1099]; "5" -> [5]; "1,4,9" -> [1, 4, 9]."""
    seeds: list[int] = []
    for part in text.split(","):
        if "-" in part.strip()[1:]:
            first, last = part.strip().split("-", 1)
            low, high = int(first), int(last)
            if high < low:
                raise ValueError(f"empty seed range {part!r}")
            seeds.extend(range(low, high + 1))
        else:
            seeds.append(int(part))
    return seeds


def certify(
    env_id: str,
    n_trailers: int,
    seeds: list[int],
    config: PlannerConfig | None = None,
    screen_horizon: float = DEFAULT_HORIZON,
    restarts: int = 0,
) -> dict[str, Any]:
    """Screen, plan and replay every seed; returns the certificate (with the action records).

    ``restarts``: the starts the planner did not keep safe are planned again, up to
    this many times, each time in one batch of those starts with the next planner seed
    (the search is random, and near the edge of the basin its outcome is too).

    The returned dict holds ``starts`` (one entry per seed) and ``actions`` (seed ->
    float64 array of the feasible starts' sequences, not JSON).
    """
    if isinstance(restarts, bool) or not isinstance(restarts, int) or restarts < 0:
        raise ValueError(f"restarts must be an integer >= 0, got {restarts!r}")
    env_kwargs = {"n_trailers": n_trailers}
    settings = env_settings(env_kwargs)
    core_class = core_class_of(env_id)
    count = len(seeds)
    started = time.perf_counter()
    core = core_class(settings, count)
    core.reset_rows(np.arange(count), seed_generators(seeds, count, None))
    strokes = [
        screen_start(settings, core.z[i], s=core.act[i, 1], s_dot=core.act[i, 3],
                     horizon=screen_horizon).stroke_fraction
        for i in range(count)
    ]  # fmt: skip
    screen_time = time.perf_counter() - started
    config = config or PlannerConfig()
    planner = SamplingPlanner(core_class, settings, count, config)
    started = time.perf_counter()
    steps = core_class.max_episode_steps
    planned = plan_episodes(core, planner, steps)
    first_pass_time = time.perf_counter() - started
    first_pass_safe = int(planned.safe.sum())
    simulated = planner.simulated_steps
    attempts = np.ones(count, dtype=np.int64)
    for restart in range(1, restarts + 1):
        rows = np.flatnonzero(~planned.safe)
        if rows.size == 0:
            break
        retry_core = core_class(settings, rows.size)
        retry_core.reset_rows(
            np.arange(rows.size), seed_generators([seeds[i] for i in rows], rows.size, None)
        )
        retry_config = dataclasses.replace(config, seed=config.seed + restart)
        retry_planner = SamplingPlanner(core_class, settings, rows.size, retry_config)
        retried = plan_episodes(retry_core, retry_planner, steps)
        simulated += retry_planner.simulated_steps
        attempts[rows] += 1
        saved = rows[retried.safe]
        for field in ("actions", "lengths", "failed", "band_steps"):
            getattr(planned, field)[saved] = getattr(retried, field)[retried.safe]
    planner_time = time.perf_counter() - started
    starts = []
    actions = {}
    for i, seed in enumerate(seeds):
        sequence = planned.actions[i, : planned.lengths[i]]
        outcome = replay(env_id, env_kwargs, seed, sequence) if planned.safe[i] else None
        feasible = (
            outcome is not None and outcome.safe and outcome.length == core_class.max_episode_steps
        )
        recoverable = bool(np.isfinite(strokes[i]) and strokes[i] <= 1.0)
        status = FEASIBLE if feasible else (OPEN if recoverable else NOT_RECOVERABLE)
        if feasible:
            actions[seed] = sequence.astype(np.float64)
        starts.append(
            {
                "seed": seed,
                "status": status,
                "screen_stroke_fraction": None if not np.isfinite(strokes[i]) else strokes[i],
                "planner_safe": bool(planned.safe[i]),
                "planner_length": int(planned.lengths[i]),
                "planner_attempts": int(attempts[i]),
                "replay_safe": None if outcome is None else outcome.safe,
            }
        )
    feasible_count = sum(start["status"] == FEASIBLE for start in starts)
    unrecoverable = sum(start["status"] == NOT_RECOVERABLE for start in starts)
    return {
        "env_id": env_id,
        "env_kwargs": env_kwargs,
        "seeds": [min(seeds), max(seeds)],
        "episodes": count,
        "planner": {
            **{
                key: getattr(planner.config, key)
                for key in ("samples", "horizon", "tail", "iterations", "elites", "seed")
            },
            "restarts": restarts,
            "first_pass_safe": first_pass_safe,
            "first_pass_wall_time_s": round(first_pass_time, 1),
            "simulated_steps_per_episode": simulated / count,
            "wall_time_s": round(planner_time, 1),
        },
        "screen": {"horizon_s": screen_horizon, "wall_time_s": round(screen_time, 1)},
        "feasible": feasible_count,
        "not_recoverable": unrecoverable,
        "open": count - feasible_count - unrecoverable,
        "ceiling": feasible_count / count,
        "screen_upper_estimate": 1.0 - unrecoverable / count,
        "starts": starts,
        "actions": actions,
    }


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


def ceiling_note(
    env_id: str, n_trailers: int, episodes: int, seed: int, directory: Path = CERTIFICATES_DIR
) -> str:
    """The ceiling line under a results table: the certified share of the episodes' starts.

    Only starts the certificate covers are counted; episodes outside it say so.
    """
    certificate = committed_certificate(env_id, n_trailers, directory)
    if certificate is None:
        return "ceiling: not certified (no planner for this scene, or `agents.certify` not run)"
    statuses = {start["seed"]: start["status"] for start in certificate["starts"]}
    wanted = range(seed, seed + episodes)
    first, last = certificate["seeds"]
    if any(episode_seed not in statuses for episode_seed in wanted):
        return (
            f"ceiling: certified on seeds {first}-{last} "
            f"({100 * certificate['ceiling']:.0f}% feasible), not on these episodes"
        )
    feasible = sum(statuses[episode_seed] == FEASIBLE for episode_seed in wanted)
    unrecoverable = sum(statuses[episode_seed] == NOT_RECOVERABLE for episode_seed in wanted)
    return (
        f"ceiling: {feasible}/{episodes} starts certified feasible (the planner's actions "
        f"replayed open-loop, `python -m agents.certify`); {unrecoverable} not recoverable "
        f"(screen), {episodes - feasible - unrecoverable} open"
    )


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog="python -m agents.certify", description="Certify a scene's ceiling over seeds."
    )
    parser.add_argument("--env", default="trailer_env/Reverse-v1", choices=ENV_IDS,
                        metavar="ENV_ID", help=f"one of {', '.join(ENV_IDS)}")  # fmt: skip
    parser.add_argument("--n-trailers", type=int, default=2, help="number of trailers")
    parser.add_argument("--seeds", default="1000-1099", help="e.g. 1000-1099 (default)")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    parser.add_argument("--samples", type=int, default=PlannerConfig.samples)
    parser.add_argument("--iterations", type=int, default=PlannerConfig.iterations)
    parser.add_argument(
        "--restarts",
        type=int,
        default=DEFAULT_RESTARTS,
        help="plan the starts not kept safe again, up to this many times, with new planner "
        f"seeds (default {DEFAULT_RESTARTS})",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    env_id = check_env_id(args.env)
    if args.n_trailers < 0:
        parser.error(f"argument --n-trailers: must be >= 0, got {args.n_trailers}")
    try:
        seeds = parse_seeds(args.seeds)
        config = PlannerConfig(
            samples=args.samples,
            iterations=args.iterations,
            elites=min(PlannerConfig.elites, max(1, args.samples // 4)),
        )
    except ValueError as error:
        parser.error(str(error))
    if args.out.exists() and not args.overwrite:
        parser.error(f"argument --out: {args.out} exists; pass --overwrite to replace it")
    if args.restarts < 0:
        parser.error(f"argument --restarts: must be >= 0, got {args.restarts}")
    certificate = certify(env_id, args.n_trailers, seeds, config, restarts=args.restarts)
    write_certificate(certificate, args.out, args.overwrite)
    print(markdown(certificate).split("\n\n| seed")[0])
    print(f"wrote {args.out / 'certificate.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
