"""How accurately the environments integrate the physics: integrator and step control.

A :class:`Fidelity` names one of the integrators below and says how many substeps
each control step of length ``dt`` takes:

* ``substeps=k`` (an int): k equal substeps for every environment, every step.
* ``substeps="auto"`` (the default): per environment and per step, the fewest
  substeps that keep the step stable and its estimated error below ``tolerance``
  (:mod:`trailer_env.substeps`, computed inside the jitted step).

Integrators:

* ``"rk4"``: classical RK4 (that of :class:`dynamics.Stepper`, run inside the step
  kernel) with the mass's quadratic motion evaluated exactly inside each step.
* ``"rk4-energy"``: the same with the energy-preserving rescaling. The energy is
  conserved only when the actuator does no work, so this needs ``mu = 0``
  (a passive convoy; the action then has no effect).
* ``"dopri5"``: :class:`dynamics.AdaptiveStepper`, Dormand-Prince 5(4) with its own
  per-environment step control (``rtol = atol = tolerance``, Hairer's RMS norm per
  internal step); ``substeps`` is ignored. Each environment's step size is carried
  from one control step to the next.

Bounds (:mod:`trailer_env.core`): a step's work, substeps x (n + 1) bodies summed over
the batch, is capped at :data:`~trailer_env.substeps.MAX_STEP_WORK` (2e8 body-substeps;
its time: benchmarks/README.md): fixed ``substeps`` beyond it are refused when the environment is
built, an auto step beyond it raises FloatingPointError before integrating. A step whose
result is not finite or beyond :data:`~trailer_env.kernels.DIVERGENCE_BOUND` (1e12) in
magnitude, or (auto, a substep cap binding) whose speed grew over 1000-fold
(:data:`~trailer_env.substeps.GROWTH_LIMIT`), is redone with 8 times the substeps, then
refused with FloatingPointError, the state left as it was. "dopri5" is held to the
divergence bound but not to the work budget (its own step control has its own limits).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from dynamics import AdaptiveStepper, ConvoyParams
from dynamics.adaptive import STATUS_OK
from dynamics.params import bounded_integer, bounded_real
from trailer_env.substeps import (
    HARD_MAX_SUBSTEPS,
    MAX_TOLERANCE,
    MIN_TOLERANCE,
    AccuracyWarning,
    auto_settings,
)

#: Upper bound on fixed ``substeps`` (a control step's cost grows linearly with it; the
#: measured costs are in benchmarks/README.md, "Auto fidelity").
MAX_FIXED_SUBSTEPS = 10_000


class AdaptiveIntegrator:
    """DOPRI5 for the batch, stepped outside the step kernel (``substeps`` is ignored).

    Every row keeps its step size from one call to the next. A row whose
    integration fails (too many steps, step size underflow) is set to NaN, which
    the environments report as a diverged step.
    """

    def __init__(self, params: ConvoyParams, with_pose: bool, tolerance: float) -> None:
        self._stepper = AdaptiveStepper(params, with_pose=with_pose, rtol=tolerance, atol=tolerance)
        self._step_size = np.zeros(0)

    def step(self, z: np.ndarray, act: np.ndarray, dt: float, substeps: np.ndarray) -> None:
        """Advance ``z`` (B, width) and ``act`` (B, 6) by ``dt`` in place."""
        if self._step_size.shape[0] != z.shape[0]:
            self._step_size = np.zeros(z.shape[0])
        stats = self._stepper.step(z, act, dt, self._step_size)
        failed = stats.status != STATUS_OK
        if failed.any():
            z[failed] = np.nan


#: The integrators a :class:`Fidelity` can name; "dopri5" chooses its own steps.
_INTEGRATORS = ("rk4", "rk4-energy", "dopri5")
_ADAPTIVE = "dopri5"


@dataclass(frozen=True)
class Fidelity:
    """Integrator and step control of the environments' physics.

    Attributes:
        integrator: "rk4" (default), "rk4-energy" (``mu = 0`` only)
            or "dopri5" (adaptive).
        substeps: An int in [1, 10_000] (:data:`MAX_FIXED_SUBSTEPS`), or "auto" (default)
            for the per-environment rule of the module docstring; either way a batch's
            step is held to the work budget (module docstring, "Bounds").
        tolerance: Bound on the estimated error of one control step in "auto" mode
            (module docstring), and ``rtol = atol`` of "dopri5"; in [1e-13, 1e-3],
            default 1e-4.
        max_substeps: Cap on the substeps the accuracy rule of "auto" may choose, in
            [1, 1_000_000] (:data:`HARD_MAX_SUBSTEPS`); the stability bound overrides it.

    A wrong type (a bool, a float for a count, a non-number tolerance) is a TypeError, an
    out-of-range value a ValueError; both name the field.
    """

    integrator: str = "rk4"
    substeps: int | str = "auto"
    tolerance: float = 1e-4
    max_substeps: int = 64

    def __post_init__(self) -> None:
        if not isinstance(self.integrator, str):
            raise TypeError(
                f"fidelity.integrator must be a str, one of {sorted(_INTEGRATORS)}, "
                f"got {type(self.integrator).__name__}"
            )
        if self.integrator not in _INTEGRATORS:
            raise ValueError(
                f"fidelity.integrator must be one of {sorted(_INTEGRATORS)}, "
                f"got {self.integrator!r}"
            )
        if isinstance(self.substeps, str):
            if self.substeps != "auto":
                raise ValueError(
                    f"fidelity.substeps must be an int in [1, {MAX_FIXED_SUBSTEPS}] or 'auto', "
                    f"got {self.substeps!r}"
                )
        else:
            if isinstance(self.substeps, bool) or not isinstance(self.substeps, (int, np.integer)):
                raise TypeError(
                    f"fidelity.substeps must be an int in [1, {MAX_FIXED_SUBSTEPS}] or 'auto', "
                    f"got {type(self.substeps).__name__} {self.substeps!r}"
                )
            count = bounded_integer("fidelity.substeps", self.substeps, 1, MAX_FIXED_SUBSTEPS)
            object.__setattr__(self, "substeps", count)
        tolerance = bounded_real("fidelity.tolerance", self.tolerance, MIN_TOLERANCE, MAX_TOLERANCE)
        object.__setattr__(self, "tolerance", tolerance)
        if isinstance(self.max_substeps, bool) or not isinstance(
            self.max_substeps, (int, np.integer)
        ):
            raise TypeError(
                f"fidelity.max_substeps must be an int in [1, {HARD_MAX_SUBSTEPS}], "
                f"got {type(self.max_substeps).__name__} {self.max_substeps!r}"
            )
        object.__setattr__(
            self,
            "max_substeps",
            bounded_integer("fidelity.max_substeps", self.max_substeps, 1, HARD_MAX_SUBSTEPS),
        )

    @property
    def uses_substeps(self) -> bool:
        """Whether the integrator takes the substep counts (False for an adaptive one)."""
        return self.integrator != _ADAPTIVE

    @property
    def auto(self) -> bool:
        """Whether substeps are chosen per environment and step."""
        return self.substeps == "auto" and self.uses_substeps

    @property
    def fixed_substeps(self) -> int:
        """The substep count when it is not chosen per step (1 for "auto" and adaptive)."""
        return self.substeps if isinstance(self.substeps, int) else 1

    @classmethod
    def coerce(cls, value: Fidelity | Mapping[str, object] | str | int | None) -> Fidelity:
        """Accept a Fidelity, a dict of its fields, an integrator name, "auto" or substeps.

        Raises:
            TypeError: For another type (bools, floats and lists included), or a dict with
                unknown field names or non-str keys.
            ValueError: For an invalid value (e.g. substeps outside [1, 10_000]).
        """
        if value is None:
            return cls()
        if isinstance(value, Fidelity):
            return value
        if isinstance(value, dict):
            fields = {"integrator", "substeps", "tolerance", "max_substeps"}
            unknown = sorted(repr(key) for key in value if key not in fields)
            if unknown:
                raise TypeError(
                    f"fidelity has unknown field(s) [{', '.join(unknown)}]; valid: {sorted(fields)}"
                )
            return cls(**value)
        if isinstance(value, str):
            return cls(substeps="auto") if value == "auto" else cls(integrator=value)
        if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
            return cls(substeps=value)
        raise TypeError(
            f"fidelity must be a Fidelity, dict, str or int, got {type(value).__name__} {value!r}"
        )

    @property
    def fused(self) -> bool:
        """Whether the integrator runs inside the step kernel ("rk4", "rk4-energy":
        :func:`trailer_env.kernels.step_serial`) rather than being called between kernels."""
        return self.integrator != _ADAPTIVE

    @property
    def preserve_energy(self) -> bool:
        """Whether the fused RK4 rescales each substep to conserve the energy ("rk4-energy")."""
        return self.integrator == "rk4-energy"

    def check_params(self, params: ConvoyParams) -> None:
        """Refuse parameters the integrator cannot integrate.

        Raises:
            ValueError: If the integrator needs a conserved energy and ``params.mu > 0``.
        """
        if self.preserve_energy and params.mu > 0.0:
            raise ValueError(
                f"fidelity.integrator {self.integrator!r} needs a conserved energy, i.e. mu = 0 "
                f"(got mu = {params.mu}); the moving mass does work on the convoy"
            )

    def outer_integrator(self, params: ConvoyParams, with_pose: bool) -> AdaptiveIntegrator | None:
        """The integrator the core calls between kernels, or None where the step kernel
        integrates (:attr:`fused`).

        Raises:
            ValueError: As :meth:`check_params`.
        """
        self.check_params(params)
        if self.fused:
            return None
        return AdaptiveIntegrator(params, with_pose, self.tolerance)

    def auto_settings(
        self, params: ConvoyParams, dt: float, planar: bool, speed_floor: float = 0.0
    ) -> np.ndarray:
        """The packed settings of the auto rule (:func:`trailer_env.substeps.auto_settings`)."""
        return auto_settings(params, dt, planar, self.tolerance, self.max_substeps, speed_floor)


__all__ = [
    "MAX_FIXED_SUBSTEPS",
    "AccuracyWarning",
    "AdaptiveIntegrator",
    "Fidelity",
]
