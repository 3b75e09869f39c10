"""Certify a scene's ceiling: which test starts some controller can keep safe.

Command line (:mod:`agents.commands.certify`)::

    python -m agents.certify --env trailer_env/Reverse-v1 --n-trailers 2 \
        --seeds 1000-1099 [--out out/certify/reverse_v1_n2] [--overwrite]

For every seed it runs the feasibility screen (:mod:`agents.oracles.screen`, a linear
programme on the linearised convoy) and the planner (:mod:`agents.oracles.planner`, on the
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

Randomised physics (``randomize=``, e.g. ``"mismatch20"``; :mod:`trailer_env.randomize`):
the drawn parameters belong to the start. The core draws each start's parameters from
its seed's generator as ``gym.make(env_id, randomize=...)`` does; the screen linearises
with them, the planner's candidates are simulated with them (its per-row parameters:
:class:`agents.oracles.planner.SamplingPlanner`), and the replay builds its env with the
same ``randomize``, so the same parameters are drawn again. The certificate records the
randomisation (``env_kwargs.randomize`` and a ``randomize`` block) and each start's
drawn parameters (``params``, as ``info["params"]`` reports them).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np

from agents.artifacts.certificates import (
    CERTIFICATES_DIR,
    FEASIBLE,
    NOT_RECOVERABLE,
    OPEN,
    committed_certificate,
    planner_name,
    start_source,
)
from agents.envs import ENV_IDS, env_settings
from agents.oracles.planner import PlannerConfig, SamplingPlanner, plan_episodes
from agents.oracles.screen import DEFAULT_HORIZON, screen_start
from agents.progress import Progress, plural
from dynamics.columns import ETA, ETA_DOT
from trailer_env.core import ConvoyCore
from trailer_env.json_types import JSONObject
from trailer_env.randomize import Randomization
from trailer_env.registry import core_class_of
from trailer_env.settings import EnvSettings
from trailer_env.vector import seed_generators

#: Default number of planner restarts on the starts a pass did not keep safe.
DEFAULT_RESTARTS = 3


#: The scenes certified by surviving with the sampling planner; goal scenes (Dock, Coast)
#: are certified by iLQR (:mod:`agents.oracles.certify_goals`), which does not take
#: randomised physics.
SURVIVAL_SCENES = ("Reverse", "Heading")


def randomize_kwarg(env_id: str, randomize: object) -> str | dict[str, list[float]] | None:
    """``randomize`` as the certificate's ``env_kwargs`` keep it: a preset's name, or the
    dict of factor ranges as ``[low, high]`` lists (JSON); None for nominal physics.

    Raises:
        TypeError: As :meth:`trailer_env.randomize.Randomization.coerce` (a bad type).
        ValueError: On an unknown preset or a bad range, or for a scene that this module
            does not certify (the goal scenes): the message names the supported ones.
    """
    if randomize is None:
        return None
    if core_class_of(env_id).scene not in SURVIVAL_SCENES:
        supported = [other for other in ENV_IDS if core_class_of(other).scene in SURVIVAL_SCENES]
        raise ValueError(
            f"randomize: certifying randomised physics is implemented for the sampling "
            f"planner (mpc) on {', '.join(supported)}, not for {env_id} (certified by iLQR)"
        )
    randomization = Randomization.coerce(randomize)
    assert randomization is not None
    if randomization.preset is not None:
        return randomization.preset
    return {name: [low, high] for name, low, high in randomization.ranges}


@dataclass(frozen=True)
class Replay:
    """An open-loop replay's outcome in a fresh env."""

    safe: bool
    length: int


def replay(env_id: str, env_kwargs: JSONObject, seed: int, actions: np.ndarray) -> Replay:
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


def certify(
    env_id: str,
    n_trailers: int,
    seeds: list[int],
    config: PlannerConfig | None = None,
    screen_horizon: float = DEFAULT_HORIZON,
    restarts: int = 0,
    randomize: str | JSONObject | Randomization | None = None,
) -> JSONObject:
    """Screen, plan and replay every seed; returns the certificate (with the action records).

    ``restarts``: the starts the planner did not keep safe are planned again, up to
    this many times, each time in one batch of those starts with the next planner seed
    (the search is random, and near the edge of the basin its outcome is too).

    ``randomize``: None (nominal physics), a preset of
    :data:`trailer_env.randomize.PRESETS` or a dict of factor ranges; each start's drawn
    parameters are screened, planned with and replayed (see the module docstring).

    The returned dict holds ``starts`` (one entry per seed) and ``actions`` (seed ->
    float64 array of the feasible starts' sequences, not JSON).

    Raises:
        ValueError: On a bad ``restarts`` or ``randomize`` (or ``randomize`` for a goal
            scene), before anything is simulated.
        TypeError: On a ``randomize`` of the wrong type.
    """
    if isinstance(restarts, bool) or not isinstance(restarts, int) or restarts < 0:
        raise ValueError(f"restarts must be an integer >= 0, got {restarts!r}")
    randomized = randomize_kwarg(env_id, randomize)
    env_kwargs: JSONObject = {"n_trailers": n_trailers}
    if randomized is not None:
        env_kwargs["randomize"] = randomized
    settings = env_settings(env_kwargs)
    core_class = core_class_of(env_id)
    count = len(seeds)
    started = time.perf_counter()
    core = core_class(settings, count)
    core.reset_rows(np.arange(count), seed_generators(seeds, count, None))
    strokes = [
        screen_start(
            start_settings(settings, core, i),
            core.z[i],
            s=core.act[i, ETA],
            s_dot=core.act[i, ETA_DOT],
            horizon=screen_horizon,
        ).stroke_fraction
        for i in range(count)
    ]
    screen_time = time.perf_counter() - started
    config = config or PlannerConfig()
    planner = SamplingPlanner(core_class, settings, count, config)
    started = time.perf_counter()
    steps = core_class.max_episode_steps
    with Progress(
        steps, f"certify {env_id}, n = {n_trailers}: planning {plural(count, 'start')}"
    ) as bar:
        planned = plan_episodes(core, planner, steps, bar)
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
        label = f"certify: restart {restart}, {plural(rows.size, 'start')}"
        with Progress(steps, label) as bar:
            retried = plan_episodes(retry_core, retry_planner, steps, bar)
        simulated += retry_planner.simulated_steps
        attempts[rows] += 1
        saved = rows[retried.safe]
        for field in ("actions", "lengths", "failed", "band_steps"):
            getattr(planned, field)[saved] = getattr(retried, field)[retried.safe]
    planner_time = time.perf_counter() - started
    starts = []
    actions = {}
    with Progress(count, "certify: replaying the safe sequences") as replays:
        for i, seed in enumerate(seeds):
            sequence = planned.actions[i, : planned.lengths[i]]
            outcome = replay(env_id, env_kwargs, seed, sequence) if planned.safe[i] else None
            replays.advance(f"seed {seed}")
            full_length = outcome is not None and outcome.length == steps
            feasible = outcome is not None and outcome.safe and full_length
            recoverable = bool(np.isfinite(strokes[i]) and strokes[i] <= 1.0)
            status = FEASIBLE if feasible else (OPEN if recoverable else NOT_RECOVERABLE)
            if feasible:
                actions[seed] = sequence.astype(np.float64)
            entry = {
                "seed": seed,
                "status": status,
                "screen_stroke_fraction": None if not np.isfinite(strokes[i]) else strokes[i],
                "planner_safe": bool(planned.safe[i]),
                "planner_length": int(planned.lengths[i]),
                "planner_attempts": int(attempts[i]),
                "replay_safe": None if outcome is None else outcome.safe,
            }
            if randomized is not None:
                entry["params"] = core.params_info(i)
            starts.append(entry)
    feasible_count = sum(start["status"] == FEASIBLE for start in starts)
    unrecoverable = sum(start["status"] == NOT_RECOVERABLE for start in starts)
    physics = {} if randomized is None else {"randomize": randomize_block(settings, randomized)}
    return {
        "env_id": env_id,
        "env_kwargs": env_kwargs,
        **physics,
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


def start_settings(settings: EnvSettings, core: ConvoyCore, row: int) -> EnvSettings:
    """The settings of row ``row``'s episode: ``settings`` with the row's drawn parameters
    and no randomisation (``settings`` itself when the physics are not randomised)."""
    if settings.randomize is None:
        return settings
    return dataclasses.replace(settings, params=core.params_of(row), randomize=None)


def randomize_block(settings: EnvSettings, randomized: str | dict[str, list[float]]) -> JSONObject:
    """What the certificate says about its randomised physics."""
    assert settings.randomize is not None
    return {
        "preset": randomized if isinstance(randomized, str) else None,
        "ranges": {name: [low, high] for name, low, high in settings.randomize.ranges},
        "meaning": "each start's parameters are drawn from its seed's generator after the "
        "start (gym.make(env_id, **env_kwargs), reset(seed=seed)); the screen, the planner "
        "and the replays use them; per start 'params' is info['params']",
    }


def ceiling_fraction(
    env_id: str, n_trailers: int, episodes: int, seed: int, directory: Path = CERTIFICATES_DIR
) -> float | None:
    """The certified share of the starts of episodes ``seed .. seed + episodes - 1``, or None
    when no committed certificate covers all of them (the leaderboard's ceiling line)."""
    certificate = committed_certificate(env_id, n_trailers, directory)
    if certificate is None:
        return None
    statuses = {start["seed"]: start["status"] for start in certificate["starts"]}
    wanted = range(seed, seed + episodes)
    if any(episode_seed not in statuses for episode_seed in wanted):
        return None
    return sum(statuses[episode_seed] == FEASIBLE for episode_seed in wanted) / episodes


def ceiling_note(
    env_id: str, n_trailers: int, episodes: int, seed: int, directory: Path = CERTIFICATES_DIR
) -> str:
    """The ceiling line under a results table: the certified share of the episodes' starts,
    and who found their records (the planner, or a witness: :mod:`agents.evaluation.witnesses`).

    Only starts the certificate covers are counted; episodes outside it say so.
    """
    certificate = committed_certificate(env_id, n_trailers, directory)
    if certificate is None:
        return "ceiling: not certified (no planner for this scene, or `agents.certify` not run)"
    # Goal scenes (Dock, Coast): the certificate of agents.oracles.certify_goals.
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
    within = set(wanted)
    counts: dict[str, int] = {}
    for start in certificate["starts"]:
        source = start_source(certificate, start) if start["seed"] in within else None
        if source is not None:
            counts[source] = counts.get(source, 0) + 1
    planner = planner_name(certificate)
    order = sorted(counts.items(), key=lambda item: (item[0] != planner, -item[1], item[0]))
    by_source = ", ".join(f"{source} {count}" for source, count in order)
    if planner == "ilqr":
        return (
            f"ceiling: {feasible}/{episodes} starts certified feasible (action records "
            f"replayed open-loop to the goal, by source: {by_source}; `python -m "
            f"agents.certify`); {episodes - feasible - unrecoverable} open (no screen for a goal)"
        )
    return (
        f"ceiling: {feasible}/{episodes} starts certified feasible (action records replayed "
        f"open-loop, by source: {by_source}; `python -m agents.certify`); {unrecoverable} not "
        f"recoverable (screen), {episodes - feasible - unrecoverable} open"
    )
