"""Certify a scene's ceiling: which test starts some controller can bring to the scene's end.

Command line (:mod:`agents.commands.certify`)::

    python -m agents.certify --env trailer_env/Reverse-v1 --n-trailers 2 \
        --seeds 1000-1099 [--out out/certify/reverse_v1_n2] [--overwrite]

The scene says what its end is (``core_class_of(env_id).objective``,
:mod:`trailer_env.objective`), and so which planner certifies it (:data:`PLANNERS`):

* a survival scene (Reverse) by surviving the full episode: the feasibility screen and
  the sampling planner (``mpc``, :func:`agents.certification.search.sampling_search`);
* a goal scene (Dock, Coast) by reaching its success: iLQR (``ilqr``,
  :func:`agents.certification.search.goal_search`).

The scene's record (:data:`agents.oracles.scenes.SCENE_ORACLES`) must name that planner
among its planners; a scene without one is not certified. Every record the planner
found is then replayed open-loop in a fresh single env (``gym.make``,
``reset(seed=seed)``; :func:`replay`). Each start is:

* ``feasible``: the replay reached the scene's end: a survival scene's full episode
  kept safe (never folded, never left the task, never in the singular band), a goal
  scene's success at the record's last step; the record is kept (float64, one action per
  step: feasibility is a closed-loop property and its record must be the exact trace;
  open-loop over 20 s the unstable convoy amplifies a float32 rounding by about e^20);
* ``not recoverable``: the screen found no recovery within the rail's stroke (a
  statement about the linearisation; survival scenes only: no screen proves a goal
  unreachable);
* ``open``: neither.

The ceiling is the feasible fraction (a lower bound on what any controller can reach;
``1 - not recoverable`` is the screen's upper estimate).

Randomised physics (``randomize=``, e.g. ``"mismatch20"``; :mod:`trailer_env.randomize`;
survival scenes): the drawn parameters belong to the start. The core draws each start's
parameters from its seed's generator as ``gym.make(env_id, randomize=...)`` does; the
screen linearises with them, the planner's candidates are simulated with them (its
per-row parameters: :class:`agents.oracles.planner.SamplingPlanner`), and the replay
builds its env with the same ``randomize``, so the same parameters are drawn again. The
certificate records the randomisation (``env_kwargs.randomize`` and a ``randomize``
block) and each start's drawn parameters (``params``, as ``info["params"]`` reports them).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from agents.artifacts.certificates import (
    FEASIBLE,
    NOT_RECOVERABLE,
    OPEN,
    Certificate,
    CertificateEnv,
    CertificateStart,
    Certified,
    RandomizePart,
    Status,
)
from agents.certification.search import (
    Search,
    check_closed_loop,
    goal_search,
    sampling_search,
)
from agents.envs import ENV_IDS, MakeKwargs, env_settings
from agents.oracles.ilqr import ILQRConfig
from agents.oracles.planner import PlannerConfig
from agents.oracles.scenes import scene_oracle
from agents.oracles.screen import DEFAULT_HORIZON
from agents.progress import Progress
from trailer_env.objective import Objective
from trailer_env.randomize import Randomization
from trailer_env.registry import core_class_of
from trailer_env.settings import EnvSettings

#: What a goal scene's certificate says its replays reach.
GOAL_SUCCESS = "the scene's success (Dock: docked; Coast: straight), replayed"
#: What a randomised certificate says of its starts' parameters.
RANDOMIZE_MEANING = (
    "each start's parameters are drawn from its seed's generator after the start "
    "(gym.make(env_id, **env_kwargs), reset(seed=seed)); the screen, the planner and the "
    "replays use them; per start 'params' is info['params']"
)


@dataclass(frozen=True)
class Certifier:
    """A certifying planner (a record of :data:`PLANNERS`).

    Attributes:
        objective: The scenes it certifies: those whose core declares this objective.
        restarts: Its default number of restarts.
        refusal: Why it does not certify a scene of the other objective (``{env_id}``
            and ``{scenes}``, the scenes it does certify, are filled in).
    """

    objective: Objective
    restarts: int
    refusal: str


#: The certifying planners by name (``--planner``): the sampling planner certifies the
#: survival scenes, iLQR the goal scenes.
PLANNERS: dict[str, Certifier] = {
    "mpc": Certifier(
        objective=Objective.SURVIVAL,
        restarts=3,
        refusal="the sampling planner (mpc) keeps a convoy safe but does not steer it to "
        "{env_id}'s goal; certify it with --planner ilqr",
    ),
    "ilqr": Certifier(
        objective=Objective.GOAL,
        restarts=2,
        refusal="{env_id} is certified by surviving the full episode with the sampling "
        "planner; use --planner mpc (ilqr certifies the goal scenes {scenes})",
    ),
}


def certifying_planner(env_id: str) -> str:
    """The planner that certifies ``env_id``: the one of :data:`PLANNERS` for its scene's
    objective.

    Raises:
        ValueError: For an id that is not registered, or a scene whose record
            (:data:`agents.oracles.scenes.SCENE_ORACLES`) does not name that planner.
    """
    objective = core_class_of(env_id).objective
    name = next(name for name, record in PLANNERS.items() if record.objective is objective)
    if name not in scene_oracle(env_id).planners:
        raise ValueError(
            f"no planner certifies {env_id}: its scene's record (agents.oracles.scenes) "
            f"does not name {name}, the planner of its {objective.value} objective"
        )
    return name


def certified_scenes(planner: str) -> list[str]:
    """The scenes (a core's ``scene``, in registry order, once each) ``planner`` certifies."""
    scenes: list[str] = []
    for env_id in ENV_IDS:
        scene = core_class_of(env_id).scene
        if scene not in scenes and _certifies(planner, env_id):
            scenes.append(scene)
    return scenes


def _certifies(planner: str, env_id: str) -> bool:
    try:
        return certifying_planner(env_id) == planner
    except ValueError:
        return False


def planner_problem(env_id: str, planner: str | None) -> str | None:
    """Why ``planner`` cannot certify ``env_id`` (None if it can; for None, the scene's
    own planner: why none certifies it).

    Raises:
        ValueError: For an id that is not registered.
    """
    try:
        own = certifying_planner(env_id)
    except ValueError as error:
        return str(error)
    if planner is None or planner == own:
        return None
    if planner not in PLANNERS:
        return f"unknown planner {planner!r}; choose one of {list(PLANNERS)}"
    scenes = " and ".join(certified_scenes(planner))
    return PLANNERS[planner].refusal.format(env_id=env_id, scenes=scenes)


def randomize_kwarg(env_id: str, randomize: object) -> str | dict[str, list[float]] | None:
    """``randomize`` as the certificate's ``env_kwargs`` keep it: a preset's name, or the
    dict of factor ranges as ``[low, high]`` lists (JSON); None for nominal physics.

    Raises:
        TypeError: As :meth:`trailer_env.randomize.Randomization.coerce` (a bad type).
        ValueError: On an unknown preset or a bad range, or for a goal scene (iLQR does
            not take randomised physics): the message names the supported scenes.
    """
    if randomize is None:
        return None
    if core_class_of(env_id).objective is not Objective.SURVIVAL:
        supported = [
            other for other in ENV_IDS if core_class_of(other).objective is Objective.SURVIVAL
        ]
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
    """An open-loop replay's outcome in a fresh env.

    Attributes:
        success: The episode ended (terminated) in the scene's success.
        safe: Never in the singular band and not terminated as a failure.
        length: Steps played (up to the episode's end or the record's).
        feasible: The record reached the scene's end: a goal scene's success at the
            record's last step, a survival scene's full episode kept safe.
    """

    success: bool
    safe: bool
    length: int
    feasible: bool


def replay(env_id: str, env_kwargs: MakeKwargs, seed: int, actions: np.ndarray) -> Replay:
    """Play ``actions`` (steps,) or (steps, action_dim) open-loop from ``reset(seed=seed)``
    in a fresh ``gym.make(env_id, **env_kwargs)``, up to the episode's end or the last
    action; the scene's objective says which outcome is :attr:`Replay.feasible`."""
    core_class = core_class_of(env_id)
    keywords: dict[str, Any] = dict(env_kwargs)  # gym.make types each keyword
    env = gym.make(env_id, **keywords)
    env.reset(seed=seed)
    sequence = np.asarray(actions, dtype=np.float64).reshape(len(actions), -1)
    length = 0
    safe = True
    success = False
    for action in sequence:
        _, _, terminated, truncated, info = env.step(action)
        length += 1
        if info["cost"] > 0.0 or (terminated and not info["is_success"]):
            safe = False
        if terminated or truncated:
            success = bool(terminated and info["is_success"])
            break
    env.close()
    if core_class.objective is Objective.GOAL:
        feasible = success and length == len(sequence)
    else:
        feasible = safe and length == core_class.max_episode_steps
    return Replay(success, safe, length, feasible)


def _is_goal(env_id: str) -> bool:
    return core_class_of(env_id).objective is Objective.GOAL


def check_restarts(restarts: object) -> int:
    """``restarts`` if it is an integer >= 0.

    Raises:
        ValueError: Otherwise, naming it.
    """
    if isinstance(restarts, bool) or not isinstance(restarts, int) or restarts < 0:
        raise ValueError(f"restarts must be an integer >= 0, got {restarts!r}")
    return restarts


def certify(
    env_id: str,
    n_trailers: int,
    seeds: list[int],
    config: PlannerConfig | ILQRConfig | None = None,
    restarts: int | None = None,
    *,
    randomize: str | Mapping[str, object] | Randomization | None = None,
    closed_loop: str | None = None,
    screen_horizon: float = DEFAULT_HORIZON,
) -> Certified:
    """Plan every seed's start with the planner of the scene's objective
    (:func:`certifying_planner`), replay the records and return the certificate with the
    records of its feasible starts.

    ``config``: the planner's settings (:class:`~agents.oracles.planner.PlannerConfig`
    for ``mpc``, :class:`~agents.oracles.ilqr.ILQRConfig` for ``ilqr``; None: the
    defaults). ``restarts``: how often the starts a pass did not settle are planned again
    (None: the planner's default, :attr:`Certifier.restarts`). ``randomize`` (survival
    scenes): None (nominal physics), a preset of :data:`trailer_env.randomize.PRESETS` or
    a dict of factor ranges. ``closed_loop`` (goal scenes): an integrator of
    :data:`agents.certification.search.CLOSED_LOOP_INTEGRATORS` the planner also re-plans
    every start on. ``screen_horizon``: the survival screen's horizon (s).

    Raises:
        ValueError: For a scene no planner certifies, a bad ``restarts``, ``randomize``
            or ``closed_loop``, or one given for a scene of the other objective, before
            anything is simulated.
        TypeError: On a ``config`` of the other planner's type, or a ``randomize`` of the
            wrong type.
    """
    planner = certifying_planner(env_id)
    randomized = randomize_kwarg(env_id, randomize)
    _check_request(env_id, planner, seeds, config, closed_loop)
    restarts = check_restarts(PLANNERS[planner].restarts if restarts is None else restarts)
    environment = CertificateEnv(n_trailers=n_trailers, randomize=randomized)
    settings = env_settings(environment.kwargs())
    core_class = core_class_of(env_id)
    if planner == "ilqr":
        goal_config = config if isinstance(config, ILQRConfig) else ILQRConfig()
        search = goal_search(core_class, settings, seeds, goal_config, restarts, closed_loop)
    else:
        sampling_config = config if isinstance(config, PlannerConfig) else PlannerConfig()
        search = sampling_search(
            core_class, settings, seeds, sampling_config, restarts, screen_horizon
        )
    starts, actions = replayed_starts(env_id, environment, seeds, search)
    randomized_part = None if randomized is None else randomize_part(settings, randomized)
    return Certified(_certificate(env_id, environment, randomized_part, search, starts), actions)


def _check_request(
    env_id: str, planner: str, seeds: list[int], config: object, closed_loop: str | None
) -> None:
    """Raises unless the request fits ``planner``, the scene's (see :func:`certify`)."""
    if not seeds:
        raise ValueError("seeds: certify at least one start")
    check_closed_loop(closed_loop)
    if closed_loop is not None and planner != "ilqr":
        raise ValueError(f"closed_loop: only for the goal scenes, not {env_id}")
    expected = ILQRConfig if planner == "ilqr" else PlannerConfig
    if config is not None and not isinstance(config, expected):
        raise TypeError(
            f"config must be {expected.__name__} for {env_id}, got {type(config).__name__}"
        )


def _certificate(
    env_id: str,
    environment: CertificateEnv,
    randomized: RandomizePart | None,
    search: Search,
    starts: tuple[CertificateStart, ...],
) -> Certificate:
    """The certificate of ``starts``: their counts, the ceiling and the search's parts."""
    count = len(starts)
    feasible = sum(start.status == FEASIBLE for start in starts)
    unrecoverable = sum(start.status == NOT_RECOVERABLE for start in starts)
    seeds = [start.seed for start in starts]
    return Certificate(
        env_id=env_id,
        env_kwargs=environment,
        randomize=randomized,
        seeds=(min(seeds), max(seeds)),
        episodes=count,
        planner=search.planner,
        success=GOAL_SUCCESS if _is_goal(env_id) else None,
        screen=search.screen,
        feasible=feasible,
        not_recoverable=unrecoverable,
        open=count - feasible - unrecoverable,
        ceiling=feasible / count,
        screen_upper_estimate=1.0 - unrecoverable / count,
        starts=starts,
        closed_loop=None if search.closed_loop is None else search.closed_loop[0],
    )


def replayed_starts(
    env_id: str, environment: CertificateEnv, seeds: list[int], search: Search
) -> tuple[tuple[CertificateStart, ...], dict[int, np.ndarray]]:
    """Replay every record the planner kept (safe or at the goal) and give each start its
    status: the certificate's starts, and the records of the feasible ones by seed."""
    goal = _is_goal(env_id)
    env_kwargs = environment.kwargs()
    starts = []
    actions = {}
    with Progress(len(seeds), "certify: replaying the records") as replays:
        for i, seed in enumerate(seeds):
            record = search.record(i)
            outcome = replay(env_id, env_kwargs, seed, record) if search.reached[i] else None
            replays.advance(f"seed {seed}")
            status: Status = OPEN
            if outcome is not None and outcome.feasible:
                status = FEASIBLE
                actions[seed] = record
            elif search.strokes is not None and not search.strokes[i] <= 1.0:
                status = NOT_RECOVERABLE  # inf (no stroke) or more than the rail's
            starts.append(_start(search, i, seed, status, outcome, goal))
    return tuple(starts), actions


def _start(
    search: Search, row: int, seed: int, status: Status, outcome: Replay | None, goal: bool
) -> CertificateStart:
    """Row ``row``'s start record; its replay's outcome under the scene's key."""
    stroke = None if search.strokes is None else float(search.strokes[row])
    replayed = None if outcome is None else (outcome.success if goal else outcome.safe)
    closed = search.closed_loop
    return CertificateStart(
        seed=seed,
        status=status,
        screen_stroke_fraction=stroke if stroke is not None and np.isfinite(stroke) else None,
        planner_safe=bool(search.reached[row]),
        planner_length=int(search.lengths[row]),
        planner_attempts=int(search.attempts[row]),
        replay_success=replayed if goal else None,
        replay_safe=None if goal else replayed,
        closed_loop_success=None if closed is None else bool(closed[1][row]),
        params=None if search.params is None else search.params[row],
    )


def randomize_part(
    settings: EnvSettings, randomized: str | dict[str, list[float]]
) -> RandomizePart:
    """What the certificate says about its randomised physics."""
    assert settings.randomize is not None
    return RandomizePart(
        preset=randomized if isinstance(randomized, str) else None,
        ranges={name: (low, high) for name, low, high in settings.randomize.ranges},
        meaning=RANDOMIZE_MEANING,
    )


__all__ = [
    "PLANNERS",
    "Certifier",
    "Replay",
    "certified_scenes",
    "certify",
    "certifying_planner",
    "planner_problem",
    "randomize_kwarg",
    "replay",
]
