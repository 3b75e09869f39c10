"""The compiled kernels' arguments of one batch core, packed once for the core's life.

A single environment's step takes a few microseconds, so what the kernels read and write
is built once, when the core is built (:func:`pack_kernel_arguments`), and passed as
plain tuples of the named tuples' fields, which numba unboxes faster
(:mod:`trailer_env.kernels`' docstring). The arrays are the core's own: the core reads
the ones it names (``z``, ``obs``, ``cost`` ...) from the record and they are updated in
place by every call.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dynamics.columns import ACT_WIDTH, XI
from trailer_env.kernels import DIVERGENCE_BOUND, StepConfig, StepOutputs, StepState
from trailer_env.settings import EnvSettings
from trailer_env.substeps import MAX_STEP_WORK

#: What :func:`trailer_env.kernels.observe` takes after ``(z, act, rows)``:
#: ``(n, planar, observation settings, parameters, outputs as a plain tuple)``.
ObserveArguments = tuple[int, bool, NDArray[np.float64], NDArray[np.float64], tuple[object, ...]]


def check_batch_size(settings: EnvSettings, batch_size: object) -> int:
    """``batch_size`` as an int, refused before any array is allocated when a step of the
    batch would exceed the work budget (:mod:`trailer_env.core`'s docstring, "Cost").

    Raises:
        ValueError: If it is not an integer >= 1, or fixed substeps over the batch exceed
            :data:`~trailer_env.substeps.MAX_STEP_WORK`.
    """
    if (
        isinstance(batch_size, bool)
        or not isinstance(batch_size, (int, np.integer))
        or batch_size < 1
    ):
        raise ValueError(f"batch_size must be an integer >= 1, got {batch_size!r}")
    n, size, fidelity = settings.n_trailers, int(batch_size), settings.fidelity
    if fidelity.uses_substeps:
        work = fidelity.fixed_substeps * (n + 1) * size
        if work > MAX_STEP_WORK:
            what = f"fidelity.substeps = {fidelity.substeps}"
            if fidelity.auto:
                what = "one substep each"
            raise ValueError(
                f"{size} environment(s) of {n + 1} bodies (n_trailers = {n}) with {what} "
                f"need {work:.3g} body-substeps per control step, over the budget of "
                f"{MAX_STEP_WORK:.3g} (trailer_env.substeps.MAX_STEP_WORK); use fewer "
                "environments, trailers or substeps"
            )
    return size


@dataclass(frozen=True)
class KernelArguments:
    """The step and observation kernels' arguments of one core (fixed for its life).

    Attributes:
        config, state, outputs: The step kernel's settings, the arrays it advances and
            the arrays it derives (:mod:`trailer_env.kernels`' named tuples).
        config_tuple, state_tuple, outputs_tuple: The same as plain tuples (what the
            kernels are passed).
        observe: :func:`~trailer_env.kernels.observe`'s arguments after ``(z, act, rows)``
            for a hand-built state (no divergence bound).
        step_observe: The same after an integrator outside the kernel ("dopri5"): the
            divergence bound (:data:`~trailer_env.kernels.DIVERGENCE_BOUND`) applies.
        nominal_auto: The auto rule's settings for the nominal parameters.
        row_auto: The auto rule's settings per row (B, 12), updated by the draws of
            randomised physics (:mod:`trailer_env.randomize`).
    """

    config: StepConfig
    state: StepState
    outputs: StepOutputs
    config_tuple: tuple[object, ...]
    state_tuple: tuple[object, ...]
    outputs_tuple: tuple[object, ...]
    observe: ObserveArguments
    step_observe: ObserveArguments
    nominal_auto: NDArray[np.float64]
    row_auto: NDArray[np.float64]


def pack_kernel_arguments(
    settings: EnvSettings,
    size: int,
    with_pose: bool,
    obs_dim: int,
    pv: NDArray[np.float64],
    per_row: bool,
) -> KernelArguments:
    """The kernel arguments of a batch of ``size`` rows, with their arrays allocated.

    Args:
        settings: The batch's settings.
        size: B.
        with_pose: Whether the state carries the cart's pose (x, y, theta).
        obs_dim: The observation's width.
        pv: The packed parameters: one vector, or one row per environment (``per_row``).
        per_row: Whether the parameters (and so the auto rule's settings) are per row.
    """
    n, params, fidelity = settings.n_trailers, settings.params, settings.fidelity
    planar = settings.actuator.planar
    z = np.zeros((size, n + (5 if with_pose else 2)))
    act = np.zeros((size, ACT_WIDTH))
    act[:, XI] = params.b
    # The last entry bounds the values a row may hold: none for hand-built states, the
    # divergence bound for a step's result (kernels.DIVERGENCE_BOUND).
    observe_settings = np.array(
        [
            params.b,
            params.s_max,
            settings.rail_speed_max,
            settings.singular_band,
            settings.fold_angle,
            np.inf,
        ]
    )
    step_observe_settings = observe_settings.copy()
    step_observe_settings[-1] = DIVERGENCE_BOUND
    nominal_auto = fidelity.auto_settings(
        params, settings.dt, planar, settings.rail_speed_max + settings.rail_accel_max * settings.dt
    )
    row_auto = np.tile(nominal_auto, (size, 1))
    config = StepConfig(
        mode=settings.actuator.code,
        b=float(params.b),
        s_max=float(params.s_max),
        accel_max=float(settings.rail_accel_max),
        dt=float(settings.dt),
        frequency=float(settings.servo_frequency),
        auto=bool(fidelity.auto),
        auto_settings=row_auto if per_row else nominal_auto,
        pv=pv,
        n=n,
        with_pose=with_pose,
        preserve_energy=fidelity.preserve_energy,
        planar=planar,
        obs_settings=step_observe_settings,
    )
    state = StepState(
        z=z,
        act=act,
        substeps=np.full(size, fidelity.fixed_substeps, dtype=np.int64),
        z_backup=np.empty_like(z),
        act_backup=np.empty_like(act),
        target_energy=np.full(size, np.nan),
        exceeded=np.zeros(size, dtype=bool),
    )
    outputs = StepOutputs(
        obs=np.zeros((size, obs_dim), dtype=np.float32),
        margin=np.ones(size),
        cost=np.zeros(size),
        jackknifed=np.zeros(size, dtype=bool),
        energy=np.zeros(size),
        nonfinite=np.zeros(size, dtype=bool),
        hitch_trig=np.zeros((size, 2 * n)),
    )
    plain_outputs = tuple(outputs)
    return KernelArguments(
        config=config,
        state=state,
        outputs=outputs,
        config_tuple=tuple(config),
        state_tuple=tuple(state),
        outputs_tuple=plain_outputs,
        observe=(n, planar, observe_settings, pv, plain_outputs),
        step_observe=(n, planar, step_observe_settings, pv, plain_outputs),
        nominal_auto=nominal_auto,
        row_auto=row_auto,
    )


__all__ = ["KernelArguments", "ObserveArguments", "check_batch_size", "pack_kernel_arguments"]
