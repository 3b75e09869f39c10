"""The planners as labellers of a batch core's rows: what DAgger's experts that plan are.

:class:`PrivilegedExpert` (the sampling planner, one per count of trailers, each row
planned with its true parameters under randomised physics; its decisions depend on its
random stream, seeded with the run's seed, and its warm start) and :class:`ILQRExpert`
(the deterministic iLQR planner: one count, the nominal parameters) satisfy
:class:`Labeller`. The table of experts, these and the trained policies, is
:data:`agents.policies.experts.EXPERTS`.
"""

from __future__ import annotations

import dataclasses
from typing import Protocol

import numpy as np

from agents.oracles.ilqr import ILQRConfig, ILQRPlanner
from agents.oracles.planner import PlannerConfig, SamplingPlanner
from trailer_env.core import ConvoyCore
from trailer_env.core_protocol import BatchCore
from trailer_env.randomize import PARAMETERS, Randomization
from trailer_env.settings import EnvSettings


def randomised_parameters(randomize: Randomization | str | dict[str, object] | None) -> bool:
    """Whether ``randomize`` (settings' or a config's) draws a physical parameter."""
    ranges = Randomization.coerce(randomize)
    return ranges is not None and any(name in PARAMETERS for name in ranges.names)


class Labeller(Protocol):
    """What DAgger asks of an expert's labeller (:func:`agents.training.dagger.collect`)."""

    @property
    def config(self) -> object:
        """Its settings (a dataclass: the run's record keeps them)."""
        ...

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

    def label(self, core: BatchCore) -> np.ndarray:
        """The planner's actions (E, 1) for every row of ``core`` (a scene core of one n
        or a MixedCore of the same counts), from the exact states."""
        if core.batch_size != self.batch_size:
            raise ValueError(
                f"core has {core.batch_size} rows, the expert labels {self.batch_size}"
            )
        if not self.mixed and len(core.counts) == 1:
            (planner,) = self.planners.values()
            return planner.label(core.row_core(0))
        cores = core.count_cores()
        if len(core.counts) == 1 or sorted(cores) != sorted(self.planners):
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
        if randomised_parameters(value.randomize):
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


__all__ = ["ILQRExpert", "Labeller", "PrivilegedExpert", "randomised_parameters"]
