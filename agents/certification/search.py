"""The planners' passes over a certificate's starts: what each certifying planner found.

Both passes plan every start on the real nonlinear model, all starts in one batch from
their exact float64 states, then plan again the starts the pass did not settle
(``restarts`` times at most). They return a :class:`Search`: the action records, whether
the planner reached the scene's end with each, and the planner's and the screen's parts
of the certificate. :func:`agents.certification.certify.certify` then replays every
record in a fresh env.

* :func:`sampling_search` (survival scenes, ``mpc``): the feasibility screen
  (:mod:`agents.oracles.screen`, a linear programme on the linearised convoy) and the
  sampling planner (:mod:`agents.oracles.planner`); a restart plans the starts it did not
  keep safe with the next planner seed (the search is random, and near the edge of the
  basin its outcome is too). Under randomised physics every start is screened and
  planned with the parameters its seed draws.
* :func:`goal_search` (goal scenes, ``ilqr``): the deterministic iLQR planner
  (:mod:`agents.oracles.ilqr`, the scene's goal-reaching costs); a restart plans the
  starts that did not reach the scene's success with a longer horizon and more
  iterations (:func:`restart_config`). No screen proves that a goal start cannot reach
  its goal. ``closed_loop`` ("dopri5"): the planner (its model unchanged) also re-plans
  every step on a plant built with the adaptive Dormand-Prince integrator at
  ``rtol = atol =`` :data:`CLOSED_LOOP_TOLERANCE`.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from agents.artifacts.certificates import ClosedLoopPart, PlannerPart, ScreenPart
from agents.envs import MakeKwargs, env_settings
from agents.oracles.ilqr import ILQRConfig, ILQRPlanner
from agents.oracles.ilqr_costs import scene_horizon
from agents.oracles.planner import PlannedEpisodes, PlannerConfig, SamplingPlanner, plan_episodes
from agents.oracles.screen import screen_start
from agents.progress import Progress, plural
from dynamics.columns import ETA, ETA_DOT
from trailer_env.core import ConvoyCore
from trailer_env.settings import EnvSettings
from trailer_env.vector import seed_generators

#: The integrators a closed-loop check may run on the plant.
CLOSED_LOOP_INTEGRATORS = ("dopri5",)
#: ``rtol = atol`` of the closed-loop plant (the default fidelity's tolerance is 1e-4).
CLOSED_LOOP_TOLERANCE = 1e-8
#: How a goal restart grows the iLQR's settings (:func:`restart_config`).
RESTART_RULE = "horizon x (1 + 0.5 k), iterations + 2 k at restart k"


@dataclass(frozen=True)
class Search:
    """What a planner's pass over the starts found, one row per start.

    Attributes:
        actions: (E, steps) float64 actions, zero after each episode's end.
        lengths: (E,) steps before the end (the episode's length if none).
        reached: (E,) the planner kept the start safe for the full episode (survival)
            or reached the scene's success (goal).
        attempts: (E,) passes that planned the start (1 + its restarts).
        planner: The certificate's ``planner`` part.
        screen: The certificate's ``screen`` part.
        strokes: (E,) the screen's minimal stroke over s_max (``inf``: no stroke
            recovers the start); None where no screen applies.
        closed_loop: The closed-loop check's part, and (E,) whether each start still
            reached success re-planning on the finer plant; None when not asked.
        params: Each start's drawn parameters (``info["params"]``) under randomised
            physics; None for nominal physics.
    """

    actions: np.ndarray
    lengths: np.ndarray
    reached: np.ndarray
    attempts: np.ndarray
    planner: PlannerPart
    screen: ScreenPart
    strokes: np.ndarray | None = None
    closed_loop: tuple[ClosedLoopPart, np.ndarray] | None = None
    params: list[dict[str, float]] | None = None

    def record(self, row: int) -> np.ndarray:
        """Row ``row``'s action record: its actions up to its end, float64."""
        return self.actions[row, : self.lengths[row]].astype(np.float64)


def reset_core(core_class: type[ConvoyCore], settings: EnvSettings, seeds: list[int]) -> ConvoyCore:
    """A core with one row per seed, each reset as ``reset(seed=seed)`` resets an env."""
    core = core_class(settings, len(seeds))
    core.reset_rows(np.arange(len(seeds)), seed_generators(seeds, len(seeds), None))
    return core


def start_settings(settings: EnvSettings, core: ConvoyCore, row: int) -> EnvSettings:
    """The settings of row ``row``'s episode: ``settings`` with the row's drawn parameters
    and no randomisation (``settings`` itself when the physics are not randomised)."""
    if settings.randomize is None:
        return settings
    return dataclasses.replace(settings, params=core.params_of(row), randomize=None)


def screen_strokes(
    settings: EnvSettings, core: ConvoyCore, horizon: float
) -> tuple[np.ndarray, ScreenPart]:
    """The screen's minimal stroke fraction of every row of a reset ``core`` (each with
    its own drawn parameters) and the certificate's ``screen`` part."""
    started = time.perf_counter()
    strokes = np.array(
        [
            screen_start(
                start_settings(settings, core, i),
                core.z[i],
                s=core.act[i, ETA],
                s_dot=core.act[i, ETA_DOT],
                horizon=horizon,
            ).stroke_fraction
            for i in range(core.batch_size)
        ]
    )
    wall_time = round(time.perf_counter() - started, 1)
    return strokes, ScreenPart(horizon_s=horizon, wall_time_s=wall_time)


def sampling_search(
    core_class: type[ConvoyCore],
    settings: EnvSettings,
    seeds: list[int],
    config: PlannerConfig,
    restarts: int,
    screen_horizon: float,
) -> Search:
    """Screen and plan the start of every seed with the sampling planner, and plan the
    starts not kept safe again with the next planner seed, ``restarts`` times at most."""
    count = len(seeds)
    core = reset_core(core_class, settings, seeds)
    strokes, screen = screen_strokes(settings, core, screen_horizon)
    steps = core_class.max_episode_steps
    started = time.perf_counter()
    planner = SamplingPlanner(core_class, settings, count, config)
    label = f"certify {core_class.scene}: planning {plural(count, 'start')}"
    with Progress(steps, label) as bar:
        planned = plan_episodes(core, planner, steps, bar)
    first_pass_time = time.perf_counter() - started
    first_pass_safe = int(planned.safe.sum())
    simulated = planner.simulated_steps
    attempts = np.ones(count, dtype=np.int64)
    for restart in range(1, restarts + 1):
        rows = np.flatnonzero(~planned.safe)
        if rows.size == 0:
            break
        simulated += _sampling_restart(planned, seeds, rows, config, settings, core_class, restart)
        attempts[rows] += 1
    part = PlannerPart(
        samples=config.samples,
        horizon=config.horizon,
        tail=config.tail,
        iterations=config.iterations,
        elites=config.elites,
        seed=config.seed,
        restarts=restarts,
        first_pass_safe=first_pass_safe,
        first_pass_wall_time_s=round(first_pass_time, 1),
        simulated_steps_per_episode=simulated / count,
        wall_time_s=round(time.perf_counter() - started, 1),
    )
    params = None if settings.randomize is None else [core.params_info(i) for i in range(count)]
    return Search(
        planned.actions,
        planned.lengths,
        planned.safe.copy(),
        attempts,
        part,
        screen,
        strokes,
        params=params,
    )


def _sampling_restart(
    planned: PlannedEpisodes,
    seeds: list[int],
    rows: np.ndarray,
    config: PlannerConfig,
    settings: EnvSettings,
    core_class: type[ConvoyCore],
    restart: int,
) -> int:
    """Plan ``rows`` again with planner seed ``config.seed + restart``; the rows it keeps
    safe take its episodes in ``planned``. Returns the simulated row-steps."""
    steps = core_class.max_episode_steps
    retry_core = reset_core(core_class, settings, [seeds[i] for i in rows])
    retry_config = dataclasses.replace(config, seed=config.seed + restart)
    retry_planner = SamplingPlanner(core_class, settings, rows.size, retry_config)
    with Progress(steps, f"certify: restart {restart}, {plural(rows.size, 'start')}") as bar:
        retried = plan_episodes(retry_core, retry_planner, steps, bar)
    saved = rows[retried.safe]
    for field in ("actions", "lengths", "failed", "band_steps"):
        getattr(planned, field)[saved] = getattr(retried, field)[retried.safe]
    return retry_planner.simulated_steps


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


def check_closed_loop(closed_loop: str | None) -> None:
    """Raises ValueError unless ``closed_loop`` is None or one of the known integrators."""
    if closed_loop is not None and closed_loop not in CLOSED_LOOP_INTEGRATORS:
        raise ValueError(
            f"closed_loop must be one of {list(CLOSED_LOOP_INTEGRATORS)} or None, "
            f"got {closed_loop!r}"
        )


def goal_search(
    core_class: type[ConvoyCore],
    settings: EnvSettings,
    seeds: list[int],
    config: ILQRConfig,
    restarts: int,
    closed_loop: str | None = None,
) -> Search:
    """Drive the start of every seed with iLQR, and drive the starts that did not reach
    the scene's success again with a longer horizon and more iterations, ``restarts``
    times at most; then, with ``closed_loop``, re-plan every start on the finer plant."""
    count = len(seeds)
    core = reset_core(core_class, settings, seeds)
    steps = core_class.max_episode_steps
    started = time.perf_counter()
    label = f"certify {core_class.scene}: iLQR on {plural(count, 'start')}"
    with Progress(steps, label) as bar:
        planned, simulated = drive(core, settings, config, bar)
    first_pass_time = time.perf_counter() - started
    first_pass_success = int(planned.success.sum())
    attempts = np.ones(count, dtype=np.int64)
    for restart in range(1, restarts + 1):
        rows = np.flatnonzero(~planned.success)
        if rows.size == 0:
            break
        retry_core = reset_core(core_class, settings, [seeds[i] for i in rows])
        with Progress(steps, f"certify: restart {restart}, {plural(rows.size, 'start')}") as bar:
            retried, more = drive(
                retry_core, settings, restart_config(config, core_class, restart), bar
            )
        simulated += more
        attempts[rows] += 1
        saved = rows[retried.success]
        for field in ("actions", "lengths", "success"):
            getattr(planned, field)[saved] = getattr(retried, field)[retried.success]
    part = PlannerPart(
        name="ilqr",
        horizon=config.horizon if config.horizon is not None else scene_horizon(core_class),
        iterations=config.iterations,
        restarts=restarts,
        restart_rule=RESTART_RULE,
        jacobians=config.jacobians,
        first_pass_safe=first_pass_success,
        first_pass_wall_time_s=round(first_pass_time, 1),
        simulated_steps_per_episode=simulated / count,
        wall_time_s=round(time.perf_counter() - started, 1),
    )
    checked = None
    if closed_loop is not None:
        checked = _closed_loop(core_class, settings, seeds, config, closed_loop)
    return Search(
        planned.actions,
        planned.lengths,
        planned.success,
        attempts,
        part,
        ScreenPart(applied=False, wall_time_s=0.0),
        closed_loop=checked,
    )


def _closed_loop(
    core_class: type[ConvoyCore],
    settings: EnvSettings,
    seeds: list[int],
    config: ILQRConfig,
    integrator: str,
) -> tuple[ClosedLoopPart, np.ndarray]:
    """Re-plan every start on a plant built with ``integrator`` (the planner's model on
    ``settings``): the certificate's part and whether each start reached success."""
    started = time.perf_counter()
    fidelity = {"integrator": integrator, "tolerance": CLOSED_LOOP_TOLERANCE}
    plant_kwargs: MakeKwargs = {"n_trailers": settings.n_trailers, "fidelity": fidelity}
    plant = reset_core(core_class, env_settings(plant_kwargs), seeds)
    with Progress(core_class.max_episode_steps, f"certify: closed loop on {integrator}") as bar:
        episodes, _ = drive(plant, settings, config, bar)
    part = ClosedLoopPart(
        integrator=integrator,
        tolerance=CLOSED_LOOP_TOLERANCE,
        planner="the first pass's settings, its model on the default fidelity",
        success=int(episodes.success.sum()),
        wall_time_s=round(time.perf_counter() - started, 1),
    )
    return part, episodes.success


__all__ = [
    "CLOSED_LOOP_INTEGRATORS",
    "CLOSED_LOOP_TOLERANCE",
    "GoalEpisodes",
    "Search",
    "check_closed_loop",
    "drive",
    "goal_search",
    "reset_core",
    "restart_config",
    "sampling_search",
    "screen_strokes",
    "start_settings",
]
