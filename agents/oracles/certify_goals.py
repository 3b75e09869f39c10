"""Certify a goal scene's ceiling (Dock-v0, Coast-v0): which test starts reach the goal.

Command line (:mod:`agents.commands.certify`)::

    python -m agents.certify --env trailer_env/Dock-v0 --n-trailers 1 \
        --seeds 1000-1099 [--out out/certify/dock_n1] [--closed-loop dopri5]

The deterministic iLQR planner (:mod:`agents.oracles.ilqr`, the scene's goal-reaching
costs) drives every start on the real nonlinear model, all starts in one batch from
their exact float64 states; the starts that did not reach the scene's success are
planned again with a longer horizon and more iterations (``--restarts`` times at most,
:func:`restart_config`). Each action record is then replayed open-loop in a fresh single
env (``gym.make``, ``reset(seed=seed)``). A start is:

* ``feasible``: the replay ended in the scene's success (Dock: docked; Coast: the convoy
  straight) at the planner's step; the record is kept (float64, one action per step);
* ``not recoverable``: never given here: no screen proves that a goal start cannot
  reach its goal (Reverse's screen, :mod:`agents.oracles.screen`, is a statement about
  keeping the linearised convoy on the rail, not about reaching a pose);
* ``open``: otherwise.

``closed_loop`` ("dopri5"): the planner (its model unchanged) also re-plans every step
on a plant built with the adaptive Dormand-Prince integrator at ``rtol = atol =``
:data:`CLOSED_LOOP_TOLERANCE`; each start records whether it still reaches success.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from agents.artifacts.certificates import FEASIBLE, OPEN
from agents.envs import env_settings
from agents.oracles.ilqr import ILQRConfig, ILQRPlanner
from agents.oracles.ilqr_costs import scene_horizon
from agents.oracles.scenes import SCENE_ORACLES, scene_oracle
from agents.progress import Progress, plural
from trailer_env.core import ConvoyCore
from trailer_env.json_types import JSONObject
from trailer_env.registry import core_class_of
from trailer_env.settings import EnvSettings
from trailer_env.vector import seed_generators

#: The scenes certified by reaching their goal (their records' ``goal``).
GOAL_SCENES = tuple(scene for scene, record in SCENE_ORACLES.items() if record.goal)
#: The integrators a closed-loop check may run on the plant.
CLOSED_LOOP_INTEGRATORS = ("dopri5",)
#: ``rtol = atol`` of the closed-loop plant (the default fidelity's tolerance is 1e-4).
CLOSED_LOOP_TOLERANCE = 1e-8
#: Default number of restarts (each with a longer horizon and more iterations).
DEFAULT_GOAL_RESTARTS = 2


def is_goal_scene(env_id: str) -> bool:
    """Whether ``env_id`` is certified by reaching a goal (Dock, Coast), not by surviving
    (its record's ``goal``, :data:`agents.oracles.scenes.SCENE_ORACLES`).

    Raises:
        ValueError: For an id that is not registered.
    """
    return scene_oracle(env_id).goal


def restart_config(config: ILQRConfig, core_class: type[ConvoyCore], restart: int) -> ILQRConfig:
    """Restart ``restart`` (>= 1): the horizon 50 % longer per restart, two more iterations."""
    horizon = config.horizon if config.horizon is not None else scene_horizon(core_class)
    return dataclasses.replace(
        config,
        horizon=round(horizon * (1.0 + 0.5 * restart)),
        iterations=config.iterations + 2 * restart,
    )


@dataclass(frozen=True)
class GoalEpisodes:
    """What :func:`drive` did: actions (E, steps) float64 (zero after the end), lengths
    (E,) steps before the end (``steps`` if none), success (E,) ended in the scene's
    success."""

    actions: np.ndarray
    lengths: np.ndarray
    success: np.ndarray


def drive(
    core: ConvoyCore,
    settings: EnvSettings,
    config: ILQRConfig,
    progress: Progress | None = None,
    steps: int | None = None,
) -> tuple[GoalEpisodes, int]:
    """Run the iLQR planner (built on ``settings``) on a reset ``core``, one row per start,
    for ``steps`` steps (default the scene's episode); returns the episodes and the
    simulated row-steps.

    Ended rows are put back at their start and their warm start forgotten (their result
    is settled), so that a folded convoy is not integrated (nor differentiated) further.
    """
    core_class = type(core)
    count = core.batch_size
    steps = core_class.max_episode_steps if steps is None else steps
    planner = ILQRPlanner(core_class, settings, count, config)
    actions = np.zeros((count, steps))
    lengths = np.full(count, steps, dtype=np.int64)
    success = np.zeros(count, dtype=bool)
    running = np.ones(count, dtype=bool)
    step_action = np.zeros((count, 1))
    start_z, start_act = core.z.copy(), core.act.copy()
    for t in range(steps):
        task = {key: getattr(core, key) for key in core_class.task_keys}
        planned = planner.plan(core.z, core.act, task)[:, 0]
        step_action[:, 0] = np.where(running, planned, 0.0)
        actions[running, t] = step_action[running, 0]
        core.step(step_action)
        if progress is not None:
            progress.advance(f"step {t + 1}, {int(running.sum())} convoys running")
        ended = running & core.terminated
        lengths[ended] = t + 1
        success |= ended & core.success
        running &= ~ended
        if not running.any():
            break
        if ended.any():
            rows = np.flatnonzero(ended)
            core.z[rows] = start_z[rows]
            core.act[rows] = start_act[rows]
            core.refresh(rows)
            planner.reset(rows)
    return GoalEpisodes(actions, lengths, success), planner.simulated_steps


def reset_core(core_class: type[ConvoyCore], settings: EnvSettings, seeds: list[int]) -> ConvoyCore:
    """A core with one row per seed, each reset as ``reset(seed=seed)`` resets an env."""
    core = core_class(settings, len(seeds))
    core.reset_rows(np.arange(len(seeds)), seed_generators(seeds, len(seeds), None))
    return core


def replay_goal(
    env_id: str, env_kwargs: JSONObject, seed: int, actions: np.ndarray
) -> tuple[bool, int]:
    """Play ``actions`` open-loop from ``reset(seed=seed)`` in a fresh env: (ended in
    the scene's success, steps played)."""
    env = gym.make(env_id, **env_kwargs)
    env.reset(seed=seed)
    sequence = np.asarray(actions, dtype=np.float64).reshape(len(actions), -1)
    length = 0
    reached = False
    for action in sequence:
        _, _, terminated, truncated, info = env.step(action)
        length += 1
        if terminated or truncated:
            reached = bool(terminated and info["is_success"])
            break
    env.close()
    return reached, length


def check_closed_loop(closed_loop: str | None) -> None:
    """Raises ValueError unless ``closed_loop`` is None or one of the known integrators."""
    if closed_loop is not None and closed_loop not in CLOSED_LOOP_INTEGRATORS:
        raise ValueError(
            f"closed_loop must be one of {list(CLOSED_LOOP_INTEGRATORS)} or None, "
            f"got {closed_loop!r}"
        )


def certify_goals(
    env_id: str,
    n_trailers: int,
    seeds: list[int],
    config: ILQRConfig | None = None,
    restarts: int = DEFAULT_GOAL_RESTARTS,
    closed_loop: str | None = None,
) -> JSONObject:
    """Plan, replay and (optionally) re-plan under ``closed_loop`` every seed of a goal
    scene; returns the certificate (the format of :mod:`agents.oracles.certify`).

    Raises:
        ValueError: For a scene that is not a goal scene, a bad ``restarts`` or
            ``closed_loop``.
    """
    if not is_goal_scene(env_id):
        raise ValueError(f"{env_id} is not a goal scene ({', '.join(GOAL_SCENES)})")
    if isinstance(restarts, bool) or not isinstance(restarts, int) or restarts < 0:
        raise ValueError(f"restarts must be an integer >= 0, got {restarts!r}")
    check_closed_loop(closed_loop)
    config = config or ILQRConfig()
    env_kwargs = {"n_trailers": n_trailers}
    settings = env_settings(env_kwargs)
    core_class = core_class_of(env_id)
    count = len(seeds)
    steps = core_class.max_episode_steps
    started = time.perf_counter()
    label = f"certify {env_id}, n = {n_trailers}: iLQR on {plural(count, 'start')}"
    with Progress(steps, label) as bar:
        planned, simulated = drive(reset_core(core_class, settings, seeds), settings, config, bar)
    first_pass_time = time.perf_counter() - started
    first_pass_success = int(planned.success.sum())
    attempts = np.ones(count, dtype=np.int64)
    for restart in range(1, restarts + 1):
        rows = np.flatnonzero(~planned.success)
        if rows.size == 0:
            break
        retry = restart_config(config, core_class, restart)
        core = reset_core(core_class, settings, [seeds[i] for i in rows])
        with Progress(
            steps, f"certify: restart {restart}, {plural(int(rows.size), 'start')}"
        ) as bar:
            retried, more = drive(core, settings, retry, bar)
        simulated += more
        attempts[rows] += 1
        saved = rows[retried.success]
        for field in ("actions", "lengths", "success"):
            getattr(planned, field)[saved] = getattr(retried, field)[retried.success]
    planner_time = time.perf_counter() - started
    closed: JSONObject | None = None
    closed_success = np.zeros(count, dtype=bool)
    if closed_loop is not None:
        started = time.perf_counter()
        fidelity = {"integrator": closed_loop, "tolerance": CLOSED_LOOP_TOLERANCE}
        plant = reset_core(core_class, env_settings({**env_kwargs, "fidelity": fidelity}), seeds)
        with Progress(steps, f"certify: closed loop on {closed_loop}") as bar:
            closed_run, _ = drive(plant, settings, config, bar)
        closed_success = closed_run.success
        closed = {
            "integrator": closed_loop,
            "tolerance": CLOSED_LOOP_TOLERANCE,
            "planner": "the first pass's settings, its model on the default fidelity",
            "success": int(closed_success.sum()),
            "wall_time_s": round(time.perf_counter() - started, 1),
        }
    starts = []
    actions = {}
    with Progress(count, "certify: replaying the records") as replays:
        for i, seed in enumerate(seeds):
            sequence = planned.actions[i, : planned.lengths[i]]
            outcome = None
            if planned.success[i]:
                outcome = replay_goal(env_id, env_kwargs, seed, sequence)
            replays.advance(f"seed {seed}")
            feasible = outcome is not None and outcome == (True, int(planned.lengths[i]))
            if feasible:
                actions[seed] = sequence.astype(np.float64)
            start: JSONObject = {
                "seed": seed,
                "status": FEASIBLE if feasible else OPEN,
                "screen_stroke_fraction": None,
                "planner_safe": bool(planned.success[i]),
                "planner_length": int(planned.lengths[i]),
                "planner_attempts": int(attempts[i]),
                "replay_success": None if outcome is None else outcome[0],
            }
            if closed_loop is not None:
                start["closed_loop_success"] = bool(closed_success[i])
            starts.append(start)
    feasible_count = sum(start["status"] == FEASIBLE for start in starts)
    certificate: JSONObject = {
        "env_id": env_id,
        "env_kwargs": env_kwargs,
        "seeds": [min(seeds), max(seeds)],
        "episodes": count,
        "planner": {
            "name": "ilqr",
            "horizon": config.horizon if config.horizon is not None else scene_horizon(core_class),
            "iterations": config.iterations,
            "restarts": restarts,
            "restart_rule": "horizon x (1 + 0.5 k), iterations + 2 k at restart k",
            "first_pass_safe": first_pass_success,
            "first_pass_wall_time_s": round(first_pass_time, 1),
            "simulated_steps_per_episode": simulated / count,
            "wall_time_s": round(planner_time, 1),
        },
        "success": "the scene's success (Dock: docked; Coast: straight), replayed",
        "screen": {"applied": False, "wall_time_s": 0.0},
        "feasible": feasible_count,
        "not_recoverable": 0,
        "open": count - feasible_count,
        "ceiling": feasible_count / count,
        "screen_upper_estimate": 1.0,
        "starts": starts,
        "actions": actions,
    }
    if closed is not None:
        certificate["closed_loop"] = closed
    return certificate


__all__ = [
    "CLOSED_LOOP_INTEGRATORS",
    "GOAL_SCENES",
    "GoalEpisodes",
    "certify_goals",
    "check_closed_loop",
    "drive",
    "is_goal_scene",
    "replay_goal",
    "restart_config",
]
