"""How accurately the environments integrate the physics: integrator name and step control.

A :class:`Fidelity` names an integrator from a small registry and says how many
substeps each control step of length ``dt`` takes:

* ``substeps=k`` (an int): k equal substeps for every environment, every step.
* ``substeps="auto"`` (the default): per environment and per step, the fewest
  substeps ``k`` (at most ``max_substeps``) such that the dimensionless step
  ``h * max(|u| / l, |omega|)`` with ``h = dt / k`` stays below ``tolerance``.
  The rates ``|u| / l`` and ``|omega|`` bound the hitch angles' and the heading's
  rates of change (physics.md section 3), i.e. the eigenvalues of the linearised
  flow near a straight convoy (section 6). Classical RK4 is stable up to about
  2.785 on the negative real axis; the default tolerance 0.1 stays far below that
  and keeps RK4's local error near (0.1)^5 / 120, about 1e-7 relative, per substep.

Integrators (see :func:`register_integrator` to add one, e.g. an adaptive
Dormand-Prince integrator that ignores ``substeps`` and reads ``tolerance``):

* ``"rk4"``: :class:`dynamics.Stepper`, classical RK4 with the mass's quadratic
  motion evaluated exactly inside each step.
* ``"rk4-energy"``: the same with the energy-preserving rescaling. The energy is
  conserved only when the actuator does no work, so this needs ``mu = 0``
  (a passive convoy; the action then has no effect).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numba import njit

from dynamics import ConvoyParams, Stepper


class BatchIntegrator(Protocol):
    """What the environments call once per control step, for the whole batch."""

    def step(self, z: np.ndarray, act: np.ndarray, dt: float, substeps: np.ndarray) -> None:
        """Advance ``z`` (B, width) and the mass state ``act`` (B, 6) by ``dt`` in place."""


IntegratorFactory = Callable[[ConvoyParams, bool, "Fidelity"], BatchIntegrator]


@dataclass(frozen=True)
class IntegratorSpec:
    """A registered integrator.

    Attributes:
        factory: ``factory(params, with_pose, fidelity)`` builds the batch integrator.
        conserved_energy_only: Valid only when the energy is conserved (``mu = 0``).
        uses_substeps: False for an adaptive integrator that chooses its own steps
            (the environments then pass ``substeps`` = 1 and it reads ``fidelity.tolerance``).
    """

    factory: IntegratorFactory
    conserved_energy_only: bool = False
    uses_substeps: bool = True


_INTEGRATORS: dict[str, IntegratorSpec] = {
    "rk4": IntegratorSpec(lambda params, with_pose, _: Stepper(params, with_pose=with_pose)),
    "rk4-energy": IntegratorSpec(
        lambda params, with_pose, _: Stepper(params, with_pose=with_pose, preserve_energy=True),
        conserved_energy_only=True,
    ),
}


def register_integrator(name: str, spec: IntegratorSpec) -> None:
    """Make ``Fidelity(integrator=name)`` available (replaces an existing entry of that name)."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"integrator name must be a non-empty string, got {name!r}")
    _INTEGRATORS[name] = spec


def integrator_names() -> tuple[str, ...]:
    """Names accepted by ``Fidelity.integrator``."""
    return tuple(_INTEGRATORS)


@dataclass(frozen=True)
class Fidelity:
    """Integrator and step control of the environments' physics.

    Attributes:
        integrator: A registered name: "rk4" (default) or "rk4-energy" (``mu = 0`` only).
        substeps: An int >= 1, or "auto" (default) for the per-environment rule of
            the module docstring.
        tolerance: Bound on the dimensionless substep ``h * max(|u| / l, |omega|)`` in
            "auto" mode (and the accuracy target of adaptive integrators), in (0, 2.5].
        max_substeps: Cap on the substeps "auto" may choose, >= 1.
    """

    integrator: str = "rk4"
    substeps: int | str = "auto"
    tolerance: float = 0.1
    max_substeps: int = 64

    def __post_init__(self) -> None:
        if self.integrator not in _INTEGRATORS:
            raise ValueError(
                f"fidelity.integrator must be one of {sorted(_INTEGRATORS)}, "
                f"got {self.integrator!r}"
            )
        if isinstance(self.substeps, str):
            if self.substeps != "auto":
                raise ValueError(
                    f"fidelity.substeps must be an int >= 1 or 'auto', got {self.substeps!r}"
                )
        elif isinstance(self.substeps, bool) or not isinstance(self.substeps, (int, np.integer)):
            raise ValueError(
                f"fidelity.substeps must be an int >= 1 or 'auto', got {self.substeps!r}"
            )
        elif self.substeps < 1:
            raise ValueError(f"fidelity.substeps must be >= 1, got {self.substeps}")
        else:
            object.__setattr__(self, "substeps", int(self.substeps))
        try:
            tolerance = float(self.tolerance)
        except (TypeError, ValueError):
            raise ValueError(
                f"fidelity.tolerance must be a number, got {self.tolerance!r}"
            ) from None
        if not (math.isfinite(tolerance) and 0.0 < tolerance <= 2.5):
            raise ValueError(f"fidelity.tolerance must be in (0, 2.5], got {self.tolerance!r}")
        object.__setattr__(self, "tolerance", tolerance)
        if (
            isinstance(self.max_substeps, bool)
            or not isinstance(self.max_substeps, (int, np.integer))
            or self.max_substeps < 1
        ):
            raise ValueError(
                f"fidelity.max_substeps must be an int >= 1, got {self.max_substeps!r}"
            )
        object.__setattr__(self, "max_substeps", int(self.max_substeps))

    @property
    def auto(self) -> bool:
        """Whether substeps are chosen per environment and step."""
        return self.substeps == "auto" and _INTEGRATORS[self.integrator].uses_substeps

    @classmethod
    def coerce(cls, value: Fidelity | dict[str, Any] | str | int | None) -> Fidelity:
        """Accept a Fidelity, a dict of its fields, an integrator name, "auto" or substeps."""
        if value is None:
            return cls()
        if isinstance(value, Fidelity):
            return value
        if isinstance(value, dict):
            unknown = sorted(set(value) - {"integrator", "substeps", "tolerance", "max_substeps"})
            if unknown:
                raise ValueError(f"fidelity has unknown field(s) {unknown}")
            return cls(**value)
        if isinstance(value, str):
            return cls(substeps="auto") if value == "auto" else cls(integrator=value)
        if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
            return cls(substeps=int(value))
        raise ValueError(f"fidelity must be a Fidelity, dict, str or int, got {value!r}")

    def make_integrator(self, params: ConvoyParams, with_pose: bool) -> BatchIntegrator:
        """Build the registered integrator for these parameters.

        Raises:
            ValueError: If the integrator needs a conserved energy and ``params.mu > 0``.
        """
        spec = _INTEGRATORS[self.integrator]
        if spec.conserved_energy_only and params.mu > 0.0:
            raise ValueError(
                f"fidelity.integrator {self.integrator!r} needs a conserved energy, i.e. mu = 0 "
                f"(got mu = {params.mu}); the moving mass does work on the convoy"
            )
        return spec.factory(params, with_pose, self)


@njit(cache=True)
def auto_substeps(
    z: np.ndarray, dt: float, l: float, tolerance: float, max_substeps: int, out: np.ndarray
) -> None:
    """Fewest substeps with ``(dt / k) * max(|u| / l, |omega|) <= tolerance`` per row, capped."""
    for i in range(z.shape[0]):
        rate = max(abs(z[i, 0]) / l, abs(z[i, 1]))
        count = math.ceil(dt * rate / tolerance)
        if count < 1:
            count = 1
        elif count > max_substeps:
            count = max_substeps
        out[i] = count
