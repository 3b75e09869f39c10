"""Baseline policies: the zero action, uniform random actions and the linear regulator.

Every policy maps a batch of observations ``(B, obs_dim)`` to a batch of actions
``(B, action_dim)`` in [-1, 1], so one call serves the whole native vector env.

* ``zero``: the mass stays at the centre of its rail; the convoy coasts.
* ``random``: uniform actions from a seeded generator (reproducible per seed).
* ``lqr``: :class:`trailer_env.controllers.LQRController`, a linear-quadratic
  regulator on the linearisation of the straight convoy (the mass's position and
  velocity included), gain-scheduled in the speed. It is the classical bar that
  learning has to beat.
* ``lqr-adaptive``: the same regulator re-designed for each episode's parameters (and
  n), read from the environment's core (:class:`AdaptiveLQRPolicy`, privileged: with
  ``randomize`` the drawn parameters are not in the observation unless
  ``observe_params=True``, and even then only to float32). Without randomisation it is
  ``lqr``.
* ``lqr-estimated``: the same regulator designed for parameters estimated online from the
  observations and its own actions (:class:`agents.policies.estimator.EstimatingLQRPolicy`,
  a windowed Gauss-Newton fit on the exact model; not privileged).
* ``heading-p``: :func:`trailer_env.controllers.heading_policy`, the proportional
  baseline of Heading-v0 (servo mode only).
* ``mpc``: :class:`agents.oracles.mpc_policy.MPCPolicy`, a sampling MPC on the nonlinear model
  that simulates its candidates with the scene's batched core (an oracle: it knows
  the model and reads the state; rail modes only).
* ``ilqr``: :class:`agents.oracles.ilqr_policy.ILQRPolicy`, a deterministic
  control-limited iLQR on the same core, goal-reaching on Dock and Coast (an oracle;
  rail modes only).
* ``mpc-replay``: :class:`agents.policies.replay.RecordedPolicy`, the committed
  certificate's records of that planner (not its witnesses') replayed open-loop (no
  planning: the seed given is the first episode's; the default settings only).

Each is a record of :data:`BASELINES` (:class:`Baseline`: its description, how it is
built, and for an oracle the words of the results tables' training line): a new baseline
is one record. The physics of the regulator lives in ``trailer_env.controllers``; this
module only adapts it to the batched policy interface.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from agents.envs import ENV_IDS, scene_baselines
from agents.oracles.scenes import scene_oracle
from trailer_env.controllers import LQRController, heading_policy
from trailer_env.core_protocol import BatchCore
from trailer_env.randomize import PARAMETERS
from trailer_env.registry import core_class_of
from trailer_env.settings import EnvSettings

#: A policy: observations (B, obs_dim) -> actions (B, action_dim), float32 in [-1, 1].
Policy = Callable[[np.ndarray], np.ndarray]


class ZeroPolicy:
    """The zero action for every environment of the batch."""

    def __init__(self, action_dim: int) -> None:
        self.action_dim = action_dim

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return np.zeros((np.atleast_2d(obs).shape[0], self.action_dim), dtype=np.float32)


class RandomPolicy:
    """Uniform actions in [-1, 1] drawn from a generator seeded once.

    Args:
        action_dim: Size of one action.
        seed: Seed of the generator: the same seed gives the same action sequence.
    """

    def __init__(self, action_dim: int, seed: int | None) -> None:
        self.action_dim = action_dim
        self.rng = np.random.default_rng(seed)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        count = np.atleast_2d(obs).shape[0]
        return self.rng.uniform(-1.0, 1.0, (count, self.action_dim)).astype(np.float32)


class LQRPolicy:
    """The gain-scheduled linear regulator of :mod:`trailer_env.controllers`, batched."""

    def __init__(self, settings: EnvSettings) -> None:
        self.controller = LQRController(settings)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return np.atleast_2d(self.controller(np.atleast_2d(obs)))


class PrivilegedObservation(NamedTuple):
    """What :meth:`AdaptiveLQRPolicy.observe` hands the policy: the observations and each
    row's episode parameters (B, 7), columns :data:`trailer_env.randomize.PARAMETERS`."""

    obs: np.ndarray
    params: np.ndarray


class AdaptiveLQRPolicy:
    """The LQR of :class:`LQRPolicy` designed for each row's episode parameters.

    The parameters come from the environment's core, ``core.params_batch()`` (B, 7): the
    rollouts (:func:`trailer_env.benchmark.rollout` and the project's commands) call
    :meth:`observe` with the core and pass what it returns instead of the observations.
    A design is cached per distinct parameter vector: a new episode with new draws costs
    one design (18 Riccati equations of size n + 3, ~20 ms), a step one controller call
    per distinct vector in the batch.

    Called on plain observations it uses the settings' nominal parameters, which is
    only right without randomised physics: then it refuses (ValueError).
    """

    def __init__(self, settings: EnvSettings) -> None:
        self.settings = settings
        self._nominal = np.array([getattr(settings.params, name) for name in PARAMETERS])
        self._designs: dict[tuple[float, ...], LQRController] = {}
        randomize = settings.randomize
        self._randomised = randomize is not None and any(
            name in PARAMETERS for name in randomize.names
        )

    def observe(self, core: BatchCore, obs: np.ndarray) -> PrivilegedObservation:
        """The observations and the core's per-row episode parameters (copies)."""
        drawn = core.params_batch()
        values = np.column_stack([drawn[name] for name in PARAMETERS]).astype(np.float64)
        return PrivilegedObservation(np.asarray(obs), values)

    def controller(self, values: np.ndarray) -> LQRController:
        """The regulator designed for the parameter vector ``values`` (columns PARAMETERS)."""
        key = tuple(float(value) for value in values)
        design = self._designs.get(key)
        if design is None:
            params = self.settings.params.replace(**dict(zip(PARAMETERS, key, strict=True)))
            settings = dataclasses.replace(self.settings, params=params, randomize=None)
            design = self._designs[key] = LQRController(settings)
        return design

    def __call__(self, obs: np.ndarray | PrivilegedObservation) -> np.ndarray:
        if isinstance(obs, PrivilegedObservation):
            batch, params = np.atleast_2d(obs.obs), np.atleast_2d(obs.params)
        else:
            if self._randomised:
                raise ValueError(
                    "lqr-adaptive needs each episode's drawn parameters: call it on "
                    "observe(core, obs) (trailer_env.benchmark.rollout does)"
                )
            batch = np.atleast_2d(obs)
            params = np.broadcast_to(self._nominal, (batch.shape[0], len(PARAMETERS)))
        actions = np.empty((batch.shape[0], self.settings.action_dim), dtype=np.float32)
        distinct, inverse = np.unique(params, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        for k, values in enumerate(distinct):
            rows = np.flatnonzero(inverse == k)
            actions[rows] = np.atleast_2d(self.controller(values)(batch[rows]))
        return actions


class HeadingProportionalPolicy:
    """Heading-v0's proportional baseline (servo mode), batched."""

    def __init__(self, settings: EnvSettings) -> None:
        if settings.action_mode != "servo":
            raise ValueError("the heading-p baseline needs action_mode='servo'")
        self.n_trailers = settings.n_trailers

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return np.atleast_2d(heading_policy(np.atleast_2d(obs), n_trailers=self.n_trailers))


def applicable_baselines(env_id: str) -> tuple[str, ...]:
    """The baselines that fit the scene: its default ones (:func:`agents.envs.scene_baselines`)
    then the planners of its record (:data:`agents.oracles.scenes.SCENE_ORACLES`), which
    are run only when named.

    Raises:
        ValueError: For an id that is not registered.
    """
    return (*scene_baselines(env_id), *scene_oracle(env_id).planners)


def _applies(name: str, env_id: str) -> bool:
    """Whether the baseline ``name`` (of :data:`BASELINES`) fits the scene: the scene
    names it, or it fits wherever its record's ``fits_like`` does."""
    applying = applicable_baselines(env_id)
    like = BASELINES[name].fits_like
    return name in applying or (like is not None and like in applying)


def make_baseline(name: str, settings: EnvSettings, env_id: str, seed: int | None = 0) -> Policy:
    """The baseline called ``name`` for environments with ``settings``.

    Args:
        name: One of :data:`BASELINES`.
        settings: The environment's settings (``env.unwrapped.settings``).
        env_id: The environment id: which baselines fit its scene
            (:func:`applicable_baselines`).
        seed: Seed of the random baseline.

    Raises:
        ValueError: On an unknown name or a baseline that does not fit the environment.
    """
    if name not in BASELINES:
        raise ValueError(f"unknown baseline {name!r}; choose from {sorted(BASELINES)}")
    if not _applies(name, env_id):
        fitting = [other for other in ENV_IDS if _applies(name, other)]
        raise ValueError(f"the {name} baseline is for {', '.join(fitting)}, not {env_id}")
    return BASELINES[name].build(settings, env_id, seed)


def recorded_policy(settings: EnvSettings, env_id: str, seed: int | None) -> Policy:
    """The committed planner's action records of ``env_id`` (not the witnesses', see
    :func:`agents.artifacts.certificates.planner_records`) replayed from episode seed ``seed``.

    Raises:
        ValueError: Without committed records, or for settings other than the scene's
            defaults with that n (the records are traces of the default physics).
    """
    from agents.artifacts.certificates import actions_path, planner_records
    from agents.policies.replay import RecordedPolicy
    from trailer_env.settings import settings_from_kwargs

    n = settings.n_trailers
    # The planner's records only: a witness's record (a learned policy's) is not the oracle.
    records = planner_records(env_id, n)
    if records is None:
        raise ValueError(
            f"mpc-replay: no committed action records for {env_id} with n = {n} "
            f"({actions_path(env_id, n).name}); run agents.certify or use mpc"
        )
    if settings != settings_from_kwargs(n_trailers=n):
        raise ValueError("mpc-replay replays traces of the default settings only; use mpc")
    return RecordedPolicy(records, 0 if seed is None else seed, settings.action_dim)


def _estimated(settings: EnvSettings, env_id: str, seed: int | None) -> Policy:
    from agents.policies.estimator import EstimatingLQRPolicy

    return EstimatingLQRPolicy(
        settings, core_class_of(env_id), AdaptiveLQRPolicy(settings).controller
    )


def _mpc(settings: EnvSettings, env_id: str, seed: int | None) -> Policy:
    from agents.oracles.mpc_policy import MPCPolicy

    return MPCPolicy(core_class_of(env_id), settings)


def _ilqr(settings: EnvSettings, env_id: str, seed: int | None) -> Policy:
    from agents.oracles.ilqr_policy import ILQRPolicy

    return ILQRPolicy(core_class_of(env_id), settings)


def _mpc_note(episode_steps: int) -> str:
    from agents.oracles.planner import PlannerConfig

    per_episode = PlannerConfig().steps_per_decision * episode_steps
    return f"oracle (exact model and state), {per_episode / 1000:.0f}k simulated steps per episode"


@dataclass(frozen=True)
class Baseline:
    """One baseline of :data:`BASELINES`.

    Attributes:
        description: One line for the help and the docs.
        build: ``(settings, env_id, seed) -> Policy`` (``seed``: the random baseline's).
        oracle_note: For an oracle (a planner that reads the exact state), the results
            tables' training line for it from the episode's length in steps; None for
            the others.
        fits_like: Another baseline wherever which this one fits too, though no scene
            names it (so the scenes' default lists and tables stay as they were); None:
            it fits the scenes that name it.
    """

    description: str
    build: Callable[[EnvSettings, str, int | None], Policy]
    oracle_note: Callable[[int], str] | None = None
    fits_like: str | None = None


#: Baseline name -> its record (the evaluation tables use these names). Which scenes a
#: baseline fits is the scene's (:func:`applicable_baselines`), not the record's.
BASELINES: dict[str, Baseline] = {
    "zero": Baseline(
        "zero action: the mass stays centred and the convoy coasts",
        lambda settings, env_id, seed: ZeroPolicy(settings.action_dim),
    ),
    "random": Baseline(
        "uniform random actions in [-1, 1] (seeded)",
        lambda settings, env_id, seed: RandomPolicy(settings.action_dim, seed),
    ),
    "lqr": Baseline(
        "LQR on the linearised straight convoy, mass states included (trailer_env.controllers)",
        lambda settings, env_id, seed: LQRPolicy(settings),
    ),
    "lqr-adaptive": Baseline(
        "the LQR re-designed for each episode's drawn parameters (privileged)",
        lambda settings, env_id, seed: AdaptiveLQRPolicy(settings),
        fits_like="lqr",
    ),
    "lqr-estimated": Baseline(
        "the LQR re-designed for parameters estimated online from the motion (least squares)",
        _estimated,
        fits_like="lqr",
    ),
    "heading-p": Baseline(
        "proportional heading baseline of Heading-v0 (trailer_env.controllers)",
        lambda settings, env_id, seed: HeadingProportionalPolicy(settings),
    ),
    "mpc": Baseline(
        "sampling MPC on the nonlinear model from the LQR (an oracle; agents.oracles.planner)",
        _mpc,
        _mpc_note,
    ),
    "ilqr": Baseline(
        "deterministic iLQR on the nonlinear model, box-bounded (oracle; agents.oracles.ilqr)",
        _ilqr,
        lambda steps: "oracle (exact model and state), deterministic iLQR (agents.oracles.ilqr)",
    ),
    "mpc-replay": Baseline(
        "the certified planner's committed action records, replayed (agents.certify)",
        recorded_policy,
        lambda steps: "oracle (the certified planner's committed records, replayed open-loop)",
    ),
}
