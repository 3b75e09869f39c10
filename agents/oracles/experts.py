"""The DAgger experts: the planners that can label a batch core's rows, as one table.

``python -m agents.imitate --expert NAME`` (:mod:`agents.training.imitate`) reads
:data:`EXPERTS`; each :class:`Expert` record says which scenes it fits, what it can
label (a range of trailer counts, randomised physics), its default settings and how to
build its labeller for a batch core. A scene's default expert is the first of the table
that fits it (:func:`default_expert`): ``mpc`` on the Reverse scenes, ``ilqr`` on Dock
and Coast, where the sampling planner has no cost for the goal.

* ``mpc``: the sampling planner (:class:`PrivilegedExpert`):
  one planner per count of trailers, each row planned with its true parameters under
  randomised physics. Its decisions depend on its random stream (seeded with the run's
  seed) and its warm start: two planners label the same states differently.
* ``ilqr``: the deterministic iLQR planner (:class:`ILQRExpert`), with
  ``reuse=False`` by default, so that a label is a function of the state alone (the same
  state gets the same action bits, whatever was labelled before). It plans one count of
  trailers with the nominal parameters: a range of counts and randomised physical
  parameters are refused (:meth:`Expert.problem`).

A scene fits an expert when the expert's name is among its record's ``planners``
(:data:`agents.oracles.scenes.SCENE_ORACLES` says which planners have a cost for it).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from agents.oracles.ilqr import ILQRConfig, ILQRPlanner
from agents.oracles.planner import PlannerConfig, SamplingPlanner
from agents.oracles.scenes import scene_oracle
from trailer_env.core import ConvoyCore
from trailer_env.randomize import PARAMETERS, Randomization
from trailer_env.settings import EnvSettings

#: The settings of an expert's planner.
ExpertConfig = PlannerConfig | ILQRConfig


class Labeller(Protocol):
    """What DAgger asks of an expert's labeller (:func:`agents.training.imitate.collect`)."""

    config: Any

    @property
    def simulated_steps(self) -> int:
        """Simulated row-steps so far (rollouts and derivatives)."""
        ...

    @property
    def steps_per_label(self) -> int:
        """Simulated steps one label costs (per row and control step)."""
        ...

    def reset(self, rows: np.ndarray | None = None) -> None:
        """Forget the warm starts of ``rows`` (default all)."""
        ...

    def random_streams(self) -> list[np.random.Generator]:
        """The generators its labels draw from, in a fixed order (a run's checkpoint
        saves and restores their states); none for a deterministic expert."""
        ...

    def label(self, core: ConvoyCore) -> np.ndarray:
        """Actions (E, 1) for every row of ``core`` from its exact states."""
        ...


class PrivilegedExpert:
    """The planner as a labeller of a batch core's rows: the DAgger expert.

    For a scene's own core, one :class:`SamplingPlanner` (seeded ``config.seed``); for a
    :class:`trailer_env.mixed.MixedCore` (``n_trailers=(low, high)``), one planner per
    count n, seeded ``config.seed + n``, that plans the rows whose episode has n trailers
    from their state in the count's core. Under randomised physics each row is planned
    with its TRUE parameters (``core.param_values``, see :class:`SamplingPlanner`): a
    privileged expert, the student sees only the observations.

    Args:
        core_class: The scene's core.
        settings: The settings of each count (``{n: settings}``; one entry for one n).
        batch_size: Rows of the core labelled (E).
        config: The planners' search settings.
    """

    def __init__(
        self,
        core_class: type[ConvoyCore],
        settings: dict[int, EnvSettings],
        batch_size: int,
        config: PlannerConfig | None = None,
    ) -> None:
        if not settings:
            raise ValueError("settings must hold at least one count")
        self.config = config or PlannerConfig()
        self.mixed = len(settings) > 1
        self.planners = {
            n: SamplingPlanner(
                core_class,
                value,
                batch_size,
                dataclasses.replace(self.config, seed=self.config.seed + n)
                if self.mixed
                else self.config,
            )
            for n, value in sorted(settings.items())
        }
        self.batch_size = batch_size

    @property
    def simulated_steps(self) -> int:
        return sum(planner.simulated_steps for planner in self.planners.values())

    @property
    def steps_per_label(self) -> int:
        """Simulated steps one label costs (per row and control step)."""
        return self.config.steps_per_decision

    def reset(self, rows: np.ndarray | None = None) -> None:
        """Forget the warm starts of ``rows`` (default all) in every planner."""
        for planner in self.planners.values():
            planner.reset(rows)

    def random_streams(self) -> list[np.random.Generator]:
        """Each planner's sampling generator, by count n."""
        return [planner.rng for _, planner in sorted(self.planners.items())]

    def label(self, core: Any) -> np.ndarray:
        """The planner's actions (E, 1) for every row of ``core`` (a scene core of one n
        or a MixedCore of the same counts), from the exact states."""
        if core.batch_size != self.batch_size:
            raise ValueError(
                f"core has {core.batch_size} rows, the expert labels {self.batch_size}"
            )
        if not self.mixed:
            (planner,) = self.planners.values()
            return planner.label(core)
        cores = getattr(core, "cores", None)
        if cores is None or sorted(cores) != sorted(self.planners):
            raise ValueError("the expert's counts differ from the core's")
        labels = np.zeros((self.batch_size, 1))
        for n, planner in self.planners.items():
            rows = np.flatnonzero(core.trailers == n)
            if rows.size == 0:
                continue
            sub = cores[n]
            params = sub.param_values[rows] if planner.per_row else None
            labels[rows] = planner.plan(sub.z[rows], sub.act[rows], params, rows)
        return labels


class ILQRExpert:
    """:class:`~agents.oracles.ilqr.ILQRPlanner` as a labeller of a scene core's rows.

    Args:
        core_class: The scene's core (its ``task_keys`` are read from the labelled core).
        settings: The settings of the one count (``{n: settings}``, one entry).
        batch_size: Rows of the core labelled (E).
        config: The planner's settings.

    Raises:
        ValueError: For a range of counts, or settings that randomise physical
            parameters (the planner plans every row with one set of parameters).
    """

    def __init__(
        self,
        core_class: type[ConvoyCore],
        settings: dict[int, EnvSettings],
        batch_size: int,
        config: ILQRConfig | None = None,
    ) -> None:
        if len(settings) != 1:
            raise ValueError(
                f"the ilqr expert labels one count of trailers, got counts {sorted(settings)}"
            )
        (value,) = settings.values()
        if _randomised_parameters(value.randomize):
            raise ValueError(
                "the ilqr expert plans with one set of parameters: it cannot label "
                "randomised physical parameters"
            )
        self.core_class = core_class
        self.planner = ILQRPlanner(core_class, value, batch_size, config)
        self.config = self.planner.config
        self.batch_size = self.planner.batch_size

    @property
    def simulated_steps(self) -> int:
        return self.planner.simulated_steps

    @property
    def steps_per_label(self) -> int:
        return self.planner.steps_per_decision

    def reset(self, rows: np.ndarray | None = None) -> None:
        self.planner.reset(rows)

    def random_streams(self) -> list[np.random.Generator]:
        return []  # deterministic: a label is a function of the state

    def label(self, core: ConvoyCore) -> np.ndarray:
        """The planner's actions (E, 1) for every row of ``core`` (a core of this scene
        and count), from its exact states and its task arrays.

        Raises:
            ValueError: For a core of another batch size.
        """
        if core.batch_size != self.batch_size:
            raise ValueError(
                f"core has {core.batch_size} rows, the expert labels {self.batch_size}"
            )
        task = {key: getattr(core, key) for key in self.core_class.task_keys}
        return self.planner.plan(core.z, core.act, task)


def _randomised_parameters(randomize: Randomization | str | dict[str, object] | None) -> bool:
    """Whether ``randomize`` (settings' or a config's) draws a physical parameter."""
    ranges = Randomization.coerce(randomize)
    return ranges is not None and any(name in PARAMETERS for name in ranges.names)


@dataclass(frozen=True)
class Expert:
    """One expert of :data:`EXPERTS`.

    Attributes:
        name: The ``--expert`` name (also the scene record's ``planners`` entry).
        summary: One line for the help.
        config_class: The type of its settings.
        default_config: Its settings when none are given.
        build: ``build(core_class, settings_by_count, batch_size, config, seed)``: the
            labeller (``seed``: the run's, for experts that draw random numbers).
        counts_range: Whether it labels a range of trailer counts (a generalist).
        per_row_parameters: Whether it plans each row with its own physical parameters.
        options: The ``--planner-*`` options of ``agents.imitate`` it takes (the
            :class:`ExpertConfig` fields they set).
        complete: The fields the given options imply (mpc: the elites follow the samples).
        any_scene: Whether it fits every scene (trained policies,
            :mod:`agents.policies.teachers`), not only those with a cost for it.
    """

    name: str
    summary: str
    config_class: type[Any]
    default_config: Callable[[], Any]
    build: Callable[[type[ConvoyCore], dict[int, EnvSettings], int, Any, int], Labeller]
    counts_range: bool
    per_row_parameters: bool
    options: tuple[str, ...]
    complete: Callable[[dict[str, Any]], dict[str, Any]] = dict
    any_scene: bool = False

    def fits(self, env_id: str) -> bool:
        """Whether the scene of ``env_id`` has a cost for this planner (an expert that is
        not a planner, ``any_scene``, fits every scene)."""
        return self.any_scene or self.name in scene_oracle(env_id).planners

    def problem(
        self,
        env_id: str,
        n_trailers: int | tuple[int, int],
        randomize: str | dict[str, object] | None,
    ) -> str | None:
        """Why this expert cannot label the env (None when it can); ``randomize`` must
        already be valid (:meth:`Randomization.coerce`)."""
        if not self.fits(env_id):
            fitting = [name for name, expert in EXPERTS.items() if expert.fits(env_id)]
            choice = f"use {' or '.join(fitting)}" if fitting else "no expert fits it"
            return f"the {self.name} expert has no cost for {env_id}; {choice}"
        if isinstance(n_trailers, tuple) and not self.counts_range:
            return (
                f"the {self.name} expert labels one count of trailers, not a range "
                f"({n_trailers[0]}-{n_trailers[1]}); use one n or --expert mpc"
            )
        if _randomised_parameters(randomize) and not self.per_row_parameters:
            return (
                f"the {self.name} expert plans with the nominal parameters: it cannot "
                "label randomised physical parameters; use --expert mpc"
            )
        return None

    def configure(self, **options: int | str | None) -> Any:
        """The default settings with the given ``--planner-*`` options (None: not given).

        Raises:
            TypeError: For an option this expert does not take (named).
            ValueError: For a value its settings refuse.
        """
        given = {key: value for key, value in options.items() if value is not None}
        unknown = sorted(set(given) - set(self.options))
        if unknown:
            raise TypeError(
                f"the {self.name} expert takes no planner option {unknown[0]!r} "
                f"(it takes {', '.join(self.options)})"
            )
        config: Any = self.default_config()  # dataclasses.replace checks the fields
        return dataclasses.replace(config, **self.complete(given))


def _mpc_fields(given: dict[str, Any]) -> dict[str, Any]:
    """A quarter of the candidates are the elites, as in the default (4 of 16)."""
    if "samples" not in given:
        return dict(given)
    return {**given, "elites": max(1, given["samples"] // 4)}


def _build_mpc(
    core_class: type[ConvoyCore],
    settings: dict[int, EnvSettings],
    batch_size: int,
    config: ExpertConfig,
    seed: int,
) -> Labeller:
    if not isinstance(config, PlannerConfig):
        raise TypeError(f"the mpc expert takes PlannerConfig, got {type(config).__name__}")
    return PrivilegedExpert(
        core_class, settings, batch_size, dataclasses.replace(config, seed=seed)
    )


def _build_ilqr(
    core_class: type[ConvoyCore],
    settings: dict[int, EnvSettings],
    batch_size: int,
    config: ExpertConfig,
    seed: int,
) -> Labeller:
    del seed  # the planner draws no random numbers
    if not isinstance(config, ILQRConfig):
        raise TypeError(f"the ilqr expert takes ILQRConfig, got {type(config).__name__}")
    return ILQRExpert(core_class, settings, batch_size, config)


#: The experts by name, in the order a scene's default is chosen (:func:`default_expert`).
EXPERTS: dict[str, Expert] = {
    "mpc": Expert(
        name="mpc",
        summary="the sampling planner (Reverse scenes; per-row parameters, ranges of n)",
        config_class=PlannerConfig,
        default_config=PlannerConfig,
        build=_build_mpc,
        counts_range=True,
        per_row_parameters=True,
        options=("samples", "iterations"),
        complete=_mpc_fields,
    ),
    "ilqr": Expert(
        name="ilqr",
        summary="the deterministic iLQR planner, a label per state (Reverse, Dock, Coast; one n)",
        config_class=ILQRConfig,
        default_config=lambda: ILQRConfig(reuse=False),
        build=_build_ilqr,
        counts_range=False,
        per_row_parameters=False,
        options=("iterations", "horizon"),
    ),
}


def default_expert(env_id: str) -> str:
    """The first expert of :data:`EXPERTS` that fits the scene of ``env_id``.

    Raises:
        ValueError: When none fits (naming the scene).
    """
    for name, expert in EXPERTS.items():
        if expert.fits(env_id):
            return name
    raise ValueError(f"{env_id} has no planner to imitate (no expert of {sorted(EXPERTS)} fits it)")


__all__ = [
    "EXPERTS",
    "Expert",
    "ExpertConfig",
    "ILQRExpert",
    "Labeller",
    "PrivilegedExpert",
    "default_expert",
]
