"""Baseline policies: the zero action, uniform random actions and the linear regulator.

Every policy maps a batch of observations ``(B, obs_dim)`` to a batch of actions
``(B, action_dim)`` in [-1, 1], so one call serves the whole native vector env.

* ``zero``: the mass stays at the centre of its rail; the convoy coasts.
* ``random``: uniform actions from a seeded generator (reproducible per seed).
* ``lqr``: :class:`trailer_env.controllers.LQRController`, a linear-quadratic
  regulator on the linearisation of the straight convoy (the mass's position and
  velocity included), gain-scheduled in the speed. It is the classical bar that
  learning has to beat.
* ``heading-p``: :func:`trailer_env.controllers.heading_policy`, the proportional
  baseline of Heading-v0 (servo mode only).
* ``mpc``: :class:`agents.oracles.planner.MPCPolicy`, a sampling MPC on the nonlinear model
  that simulates its candidates with the scene's batched core (an oracle: it knows
  the model and reads the state; rail modes only).
* ``ilqr``: :class:`agents.oracles.ilqr_policy.ILQRPolicy`, a deterministic
  control-limited iLQR on the same core, goal-reaching on Dock and Coast (an oracle;
  rail modes only).
* ``mpc-replay``: :class:`agents.policies.replay.RecordedPolicy`, the committed
  certificate's records of that planner replayed open-loop (no planning: the seed
  given is the first episode's; the default settings only).

The physics of the regulator lives in ``trailer_env.controllers``; this module only
adapts it to the batched policy interface.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from agents.envs import ENV_IDS, scene_baselines
from trailer_env.controllers import LQRController, heading_policy
from trailer_env.settings import EnvSettings

#: A policy: observations (B, obs_dim) -> actions (B, action_dim), float32 in [-1, 1].
Policy = Callable[[np.ndarray], np.ndarray]

#: Baseline name -> one-line description (the evaluation tables use these names).
BASELINES: dict[str, str] = {
    "zero": "zero action: the mass stays centred and the convoy coasts",
    "random": "uniform random actions in [-1, 1] (seeded)",
    "lqr": "LQR on the linearised straight convoy, mass states included (trailer_env.controllers)",
    "heading-p": "proportional heading baseline of Heading-v0 (trailer_env.controllers)",
    "mpc": "sampling MPC on the nonlinear model from the LQR (an oracle; agents.oracles.planner)",
    "ilqr": "deterministic iLQR on the nonlinear model, box-bounded (oracle; agents.oracles.ilqr)",
    "mpc-replay": "the certified planner's committed action records, replayed (agents.certify)",
}


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


class HeadingProportionalPolicy:
    """Heading-v0's proportional baseline (servo mode), batched."""

    def __init__(self, settings: EnvSettings) -> None:
        if settings.action_mode != "servo":
            raise ValueError("the heading-p baseline needs action_mode='servo'")
        self.n_trailers = settings.n_trailers

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return np.atleast_2d(heading_policy(np.atleast_2d(obs), n_trailers=self.n_trailers))


def make_baseline(name: str, settings: EnvSettings, env_id: str, seed: int | None = 0) -> Policy:
    """The baseline called ``name`` for environments with ``settings``.

    Args:
        name: One of :data:`BASELINES`.
        settings: The environment's settings (``env.unwrapped.settings``).
        env_id: The environment id: its scene declares which baselines apply
            (:func:`agents.envs.scene_baselines`).
        seed: Seed of the random baseline.

    Raises:
        ValueError: On an unknown name or a baseline that does not fit the environment.
    """
    if name in BASELINES and name not in scene_baselines(env_id, oracles=True):
        fitting = [other for other in ENV_IDS if name in scene_baselines(other, oracles=True)]
        raise ValueError(f"the {name} baseline is for {', '.join(fitting)}, not {env_id}")
    if name == "zero":
        return ZeroPolicy(settings.action_dim)
    if name == "random":
        return RandomPolicy(settings.action_dim, seed)
    if name == "lqr":
        return LQRPolicy(settings)
    if name == "heading-p":
        return HeadingProportionalPolicy(settings)
    if name == "mpc":
        from agents.oracles.planner import MPCPolicy
        from trailer_env.registry import core_class_of

        return MPCPolicy(core_class_of(env_id), settings)
    if name == "ilqr":
        from agents.oracles.ilqr_policy import ILQRPolicy
        from trailer_env.registry import core_class_of

        return ILQRPolicy(core_class_of(env_id), settings)
    if name == "mpc-replay":
        return recorded_policy(settings, env_id, seed)
    raise ValueError(f"unknown baseline {name!r}; choose from {sorted(BASELINES)}")


def recorded_policy(settings: EnvSettings, env_id: str, seed: int | None) -> Policy:
    """The committed action records of ``env_id`` replayed from episode seed ``seed``.

    Raises:
        ValueError: Without committed records, or for settings other than the scene's
            defaults with that n (the records are traces of the default physics).
    """
    from agents.artifacts.certificates import actions_path, committed_actions
    from agents.policies.replay import RecordedPolicy
    from trailer_env.settings import settings_from_kwargs

    n = settings.n_trailers
    records = committed_actions(env_id, n)
    if records is None:
        raise ValueError(
            f"mpc-replay: no committed action records for {env_id} with n = {n} "
            f"({actions_path(env_id, n).name}); run agents.certify or use mpc"
        )
    if settings != settings_from_kwargs(n_trailers=n):
        raise ValueError("mpc-replay replays traces of the default settings only; use mpc")
    return RecordedPolicy(records, 0 if seed is None else seed, settings.action_dim)
