"""The batch's arrays and its compiled physics step: what every part of the core reads.

:class:`CoreBase` declares every attribute of :class:`trailer_env.core.ConvoyCore` once
and builds them (the kernels' arguments through
:func:`trailer_env.kernel_args.pack_kernel_arguments`); the parts of the core
(:mod:`trailer_env.core_physics`, :mod:`trailer_env.core_infos`,
:mod:`trailer_env.core_retry`) and the core itself build on it. The step's contract is
in :mod:`trailer_env.core`'s docstring.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from dynamics.jit import pack_params
from dynamics.params import ConvoyParams
from trailer_env.fidelity import AdaptiveIntegrator
from trailer_env.kernel_args import KernelArguments, check_batch_size, pack_kernel_arguments
from trailer_env.kernels import (
    PARALLEL_MIN_ROWS,
    StepConfig,
    StepOutputs,
    StepState,
    clamp_rows_to_rail,
    observe,
    prepare_step,
    step_parallel,
    step_serial,
)
from trailer_env.randomize import NAMES, PARAMETERS, Randomization
from trailer_env.settings import EnvSettings

#: A step kernel's result: ``(bad action row or -1 (or OVER_BUDGET), non-finite rows,
#: rows over the tolerance)``.
StepResult = tuple[int, int, int]
#: A scene's compiled step (:attr:`CoreBase.scene_kernel`).
StepKernel = Callable[..., StepResult]
#: A scene's compiled formulas that write into its arrays (:attr:`CoreBase.scene_outcome`,
#: :attr:`trailer_env.core.ConvoyCore.start_kernel`).
SceneFunction = Callable[..., None]


class NonFiniteStateError(ValueError):
    """The state holds NaN or infinite values."""


def scene_randomization(
    randomize: Randomization | None, fixed: tuple[str, ...], scene: str
) -> Randomization | None:
    """The randomisation a scene whose formulas hold ``fixed`` parameters as one value for
    the batch draws: a preset varies the others, a dict naming one is refused.

    Raises:
        ValueError: If ``randomize`` is a dict of ranges naming a parameter of ``fixed``.
    """
    if randomize is None:
        return None
    held = sorted(set(randomize.names) & set(fixed))
    if held and randomize.preset is not None:
        # A preset applies to every scene: it varies what this one allows.
        return randomize.without(held)
    if held:
        raise ValueError(
            f"randomize: {scene}'s formulas use {held} as one value for the batch; it cannot "
            f"be randomised in this scene (a preset varies the other parameters)"
        )
    return randomize


class CoreBase:
    """The arrays of B environments of one scene and the physics step over them.

    Attributes (all arrays have leading axis B):
        z: State (u, omega, alpha_1..alpha_n[, x, y, theta]).
        act: Mass state (xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot); rail: xi = b.
        obs: Observations, float32.
        singular_margin, cost, jackknifed, energy, energy0: per environment.
        reward, terminated, success, failed: results of the last step.
        substeps: Substeps used by the last step.
        hitch_trig: sin(alpha_k) then cos(alpha_k) of every row's current state, float64
            (B, 2n): computed once per step with the observation, read by scene formulas.
        accuracy_exceeded: Rows whose last step's estimated error exceeded the fidelity's
            tolerance because a substep cap bound (auto fidelity only; see
            :mod:`trailer_env.core`'s docstring).
        factors: The episode's factors per row, columns :data:`trailer_env.randomize.NAMES`
            (1 where not randomised); ``param_values`` the parameters they give, columns
            :data:`~trailer_env.randomize.PARAMETERS` (B, 7).
        kernel_args: The kernels' arguments (:class:`trailer_env.kernel_args.KernelArguments`).
    """

    #: Whether the scene itself needs the cart's pose (x, y, theta).
    uses_pose: ClassVar[bool] = False
    #: Number of task features appended to the observation.
    n_task_features: ClassVar[int] = 0
    #: Parameters the scene's own formulas read as one value for the batch (Dock's hitch
    #: positions use ``l``): a ``randomize`` dict that names one is refused; a preset
    #: (``"mismatch10"``, ``"mismatch20"``) leaves them nominal and varies the others.
    fixed_parameters: ClassVar[tuple[str, ...]] = ()
    #: A jitted ``outcome(rows, outputs, scene)`` that writes ``reward``, ``terminated``
    #: and ``success`` of ``rows`` after a step from ``scene`` (:meth:`_scene_arguments`)
    #: and the step kernel's ``outputs``; and a jitted ``kernel(action, rows, prepare,
    #: config, state, outputs, scene)`` that calls :func:`trailer_env.kernels.step_serial`
    #: with its first six arguments, then ``outcome`` if no action was refused and no row
    #: diverged, and returns the step's result: one call per step. Batches of
    #: PARALLEL_MIN_ROWS rows or more call ``step_parallel`` and then ``outcome`` (two
    #: calls: a cached function that calls a parallel one can crash numba when loaded from
    #: its disk cache); an unfused step ("dopri5"), and a step whose diverged rows were
    #: redone with more substeps, call ``outcome`` on every row stepped once the state is
    #: final (so a refused step never wrote its results). None: the
    #: Python hooks compute them. Assign both as ``staticmethod(function)``; ``config``,
    #: ``state``, ``outputs`` and ``scene`` arrive as plain tuples of the named tuples'
    #: fields (:mod:`trailer_env.kernels`).
    scene_kernel: ClassVar[StepKernel | None] = None
    scene_outcome: ClassVar[SceneFunction | None] = None

    settings: EnvSettings
    params: ConvoyParams
    n: int
    batch_size: int
    with_pose: bool
    planar: bool
    n_common: int
    #: Where the parameter features start (``observe_params``): after the task's.
    param_offset: int
    n_param_features: int
    obs_dim: int
    randomization: Randomization | None
    kernel_args: KernelArguments
    step_config: StepConfig
    step_state: StepState
    step_outputs: StepOutputs
    z: NDArray[np.float64]
    act: NDArray[np.float64]
    substeps: NDArray[np.int64]
    obs: NDArray[np.float32]
    singular_margin: NDArray[np.float64]
    cost: NDArray[np.float64]
    jackknifed: NDArray[np.bool_]
    energy: NDArray[np.float64]
    energy0: NDArray[np.float64]
    hitch_trig: NDArray[np.float64]
    accuracy_exceeded: NDArray[np.bool_]
    reward: NDArray[np.float64]
    terminated: NDArray[np.bool_]
    success: NDArray[np.bool_]
    failed: NDArray[np.bool_]
    factors: NDArray[np.float64]
    param_values: NDArray[np.float64]
    _packed: NDArray[np.float64]
    _unscaled: NDArray[np.intp]
    _draws: tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]] | None
    _integrator: AdaptiveIntegrator | None
    _all_rows: NDArray[np.int64]
    _info_arrays: list[tuple[str, NDArray[np.generic] | None]] | None
    _scene: tuple[object, ...] | None

    def __init__(self, settings: EnvSettings, batch_size: int, *, track_pose: bool = False) -> None:
        size = check_batch_size(settings, batch_size)
        self.settings, self.params, self.n = settings, settings.params, settings.n_trailers
        self.batch_size = size
        self.with_pose = self.uses_pose or track_pose
        self.planar = settings.actuator.planar
        self.n_common = 2 + 2 * self.n + settings.actuator.mass_features
        self.param_offset = self.n_common + self.n_task_features
        self.n_param_features = len(PARAMETERS) if settings.observe_params else 0
        self.obs_dim = self.param_offset + self.n_param_features
        self.randomization = scene_randomization(
            settings.randomize, self.fixed_parameters, type(self).__name__
        )
        # Only "dopri5" is called from here; the RK4s run inside the step kernel.
        self._integrator = settings.fidelity.outer_integrator(self.params, self.with_pose)
        self._packed = pack_params(self.params)
        self.factors = np.ones((size, len(NAMES)))
        self.param_values = np.tile(self._packed, (size, 1))
        # Parameters whose nominal value is 0: a factor leaves them 0, so the factor that
        # holds, and is observed, is 1 (the draw still happens: the streams stay the same).
        self._unscaled = np.flatnonzero(self._packed == 0.0)
        self._draws = None
        # Per-row parameters reach the kernels only when a physical parameter is drawn: the
        # shared vector keeps the kernels' shared (faster) specialisation otherwise.
        per_row = False
        if self.randomization is not None:
            self._draws = (self.randomization.drawn_columns(), *self.randomization.bounds())
            per_row = any(name in PARAMETERS for name in self.randomization.names)
        pv = self.param_values if per_row else self._packed
        args = pack_kernel_arguments(settings, size, self.with_pose, self.obs_dim, pv, per_row)
        self.kernel_args = args
        self.step_config, self.step_state, self.step_outputs = args.config, args.state, args.outputs
        self.z, self.act, self.substeps = args.state.z, args.state.act, args.state.substeps
        self.accuracy_exceeded = args.state.exceeded
        outputs = args.outputs
        self.obs, self.singular_margin, self.cost = outputs.obs, outputs.margin, outputs.cost
        self.jackknifed, self.energy, self.hitch_trig = (
            outputs.jackknifed,
            outputs.energy,
            outputs.hitch_trig,
        )
        self.energy0 = np.zeros(size)
        self.reward = np.zeros(size)
        self.terminated = np.zeros(size, dtype=bool)
        self.success = np.zeros(size, dtype=bool)
        self.failed = np.zeros(size, dtype=bool)
        self._all_rows = np.arange(size, dtype=np.int64)
        self._info_arrays = None
        self._scene = None  # built on the first step (subclasses' arrays)

    # ----------------------------------------------------------------- hooks
    def _scene_arguments(self) -> tuple[object, ...]:
        """The scene kernel's last argument (a named tuple of the arrays and constants its
        formulas read and write), built once; passed to the kernels as a plain tuple."""
        return ()

    def _update_task(self, rows: slice | NDArray[np.int64]) -> None:
        """Recompute derived task quantities and ``obs[rows, n_common:]`` (rows index the batch)."""

    def _after_restore(self, rows: NDArray[np.int64]) -> None:
        """Undo a refused step's per-step bookkeeping in ``rows``, back at their states before
        it (a scene kernel's outcome has already run on the rows that did not diverge)."""

    # ----------------------------------------------------------------- physics
    def refresh(self, rows: NDArray[np.int64] | None = None) -> None:
        """Recompute everything derived from the state of ``rows`` (int array; default all).

        Call it after changing ``z`` or ``act`` by hand.
        """
        indices = self._all_rows if rows is None else np.asarray(rows, dtype=np.int64)
        if observe(self.z, self.act, indices, *self.kernel_args.observe):
            raise NonFiniteStateError("the state contains non-finite values (NaN or inf)")
        self._update_task(slice(None) if rows is None else indices)

    def _physics_step(
        self,
        action: NDArray[np.float64],
        rows: NDArray[np.int64],
        prepare: bool,
        outcome: bool = True,
    ) -> StepResult:
        """One control step of ``rows``: ``(bad action row or -1, non-finite rows, over tol.)``;
        with ``outcome``, the scene kernel's results too when no row diverged."""
        if self._integrator is not None:
            return self._unfused_step(self._integrator, action, rows, prepare)
        args = self.kernel_args
        config, state, outputs = args.config_tuple, args.state_tuple, args.outputs_tuple
        parallel = rows.size >= PARALLEL_MIN_ROWS
        result: StepResult
        if self.scene_kernel is not None and self.scene_outcome is not None and outcome:
            scene = self._scene_tuple()
            if not parallel:
                return self.scene_kernel(action, rows, prepare, config, state, outputs, scene)
            result = step_parallel(action, rows, prepare, config, state, outputs)
            if result[0] == -1 and not result[1]:
                self.scene_outcome(rows, outputs, scene)
            return result
        kernel = step_parallel if parallel else step_serial
        result = kernel(action, rows, prepare, config, state, outputs)
        return result

    def _scene_tuple(self) -> tuple[object, ...]:
        """:meth:`_scene_arguments` as the plain tuple the kernels take, built once."""
        if self._scene is None:
            self._scene = tuple(self._scene_arguments())
        return self._scene

    def _unfused_step(
        self,
        integrator: AdaptiveIntegrator,
        action: NDArray[np.float64],
        rows: NDArray[np.int64],
        prepare: bool,
    ) -> StepResult:
        over = 0
        if prepare:
            bad, over = prepare_step(
                action, rows, self.kernel_args.config_tuple, self.kernel_args.state_tuple
            )
            if bad >= 0:
                return bad, 0, 0
        dt, b, s_max = self.settings.dt, self.params.b, self.params.s_max
        if rows.size == self.batch_size:
            integrator.step(self.z, self.act, dt, self.substeps)
        else:
            z, act = self.z[rows], self.act[rows]
            integrator.step(z, act, dt, self.substeps[rows])
            self.z[rows], self.act[rows] = z, act
        clamp_rows_to_rail(self.act, rows, b, s_max)
        return -1, observe(self.z, self.act, rows, *self.kernel_args.step_observe), over


__all__ = [
    "CoreBase",
    "NonFiniteStateError",
    "SceneFunction",
    "StepKernel",
    "StepResult",
    "scene_randomization",
]
