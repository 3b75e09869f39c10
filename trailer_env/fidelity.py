"""How accurately the environments integrate the physics: integrator name and step control.

A :class:`Fidelity` names an integrator from a small registry and says how many
substeps each control step of length ``dt`` takes:

* ``substeps=k`` (an int): k equal substeps for every environment, every step.
* ``substeps="auto"`` (the default): per environment and per step, the fewest
  substeps that keep the step stable and its estimated error below ``tolerance``
  (the rule below), computed inside the jitted step (:func:`auto_substeps`).

What ``tolerance`` means. The error of one control step is the difference between
the step taken and the exact flow over ``dt`` from the same state under the same
held mass acceleration, measured as

    e = max(|du| / v, l |d omega| / v, max_k |d alpha_k|),
    v = max(|u|, l |omega|, v_mass),  v_mass = |xi_dot| + |eta_dot| + dt (|xi_ddot| + |eta_ddot|):

velocities relative to the step's speed scale (the convoy's or, when it is nearly at
rest, the mass's on the cart), hitch angles in radians. The auto rule keeps an
upper estimate of e below ``tolerance`` (default 1e-4); the pose (x, y, theta), when
integrated, follows from these.

The auto rule. With ``n`` trailers, at the start of a step (rates in 1/s):

* ``r = max(|u| c_speed, |omega|)``, ``c_speed = max(1 / l, c_cart)``:
  the trailers' eigenvalue ``|u| / l`` and the cart's ``c_cart |u|`` at a straight
  convoy, ``c_cart = |M a + mu xi| / (I0 + mu xi^2)`` with the mass at ``xi = b``
  (its largest value over the mass's square in planar mode; a lateral offset only
  lowers it), see benchmarks/README.md, "Stability";
* ``R = max(g(n) r, r_mass)``: ``g(n) = 0.55 + 0.15 n`` (:data:`CHAIN_GROWTH`)
  because RK4's error constant grows with the length of the chain, fastest for
  reversing or bent chains (measured, below), and
  ``r_mass = 0.1 (|xi_dot| + |eta_dot|) / s_max + 0.4 sqrt((|xi_ddot| + |eta_ddot|) / s_max)``
  (:data:`MASS_WEIGHTS`), the time scale of the mass's motion on its rail;
* accuracy: RK4's error over one control step of k substeps is estimated as
  ``C k (dt R / k)^5`` with ``C = 8`` (:data:`ERROR_CONSTANT`), so
  ``k_acc = ceil((C (dt R)^5 / tolerance)^(1/4))``, capped at ``max_substeps``;
* stability: ``k_stab = ceil(dt r / x_safe(n))`` with ``x_safe(n)`` =
  :data:`STABILITY_FRACTION` (0.4) times RK4's usable stability limit of the
  dimensionless step for n trailers (:data:`RK4_STABILITY_LIMITS`: 2.785 for n <= 1,
  2.10 for n = 8, 1.59 for n = 32, measured on the linearised straight convoy whose
  trailers form a Jordan block, with benchmarks/stability.py's criterion). The
  fraction is small because a state can change completely within one control step:
  a convoy reversing at ``dt |u| / l = 10`` folds within the step, its turning rate
  reaching ~2.5 ``|u| / l``; at 0.5 of the limit 2 of 1,000 runs diverged, at 0.4
  none of 3,000 (16 environments x 100 steps each under random actions, restarted at
  ``dt |u| / l`` = 0.5 .. 100 after every fold; 4 scenes, n = 0..32, rail and planar
  actuators; the accuracy rule switched off);
* ``k = max(min(k_acc, max_substeps), k_stab, 1)``: stability always wins over
  ``max_substeps`` (up to :data:`HARD_MAX_SUBSTEPS`, speeds no scene reaches).

When a cap binds (``k_acc > max_substeps`` and stability does not ask for as many, or
anything above :data:`HARD_MAX_SUBSTEPS`), the step's estimated error exceeds the
tolerance: at ``|u| = 1000`` m/s (n = 2, dt = 0.05) one step with zero action loses
12 % of the energy, at ``|u| = 1e8`` 91 %. Such a step is never silent: the
environments flag its rows (``core.accuracy_exceeded``) and issue an
:class:`AccuracyWarning` once per batch (:mod:`trailer_env.core`). Raise
``max_substeps`` to hold the tolerance there, or use ``"dopri5"``. The scenes' own
speeds never reach the cap (tests/trailer_env/test_extreme_states.py).

How the constants were measured (default parameters, dt = 0.05 unless stated):
states from all four scenes under random held servo and planar actions, n = 0..32,
their speeds scaled by 0.03 .. 30 (by homogeneity, ``dt |u| / l`` from 0.002 to 1.5);
one control step with k substeps against the same step with 8 or more times as many.
The fitted chain factor makes the error constant ``e k^4 / (dt R)^5`` flat in n (for
``g = 1`` it is 0.02 at n = 0, 0.36 at n = 2, 12 at n = 8, 4300 at n = 32, about
``(0.5 + 0.14 n)^5``); the mass weights are the smallest that keep the mass-driven
states below the convoy's constant. The largest ratio found was 3.6 for
``dt R / k <= 0.2`` (above, errors above ~1e-3, RK4 leaves its asymptotic regime:
hence ``tolerance <= 1e-3``), and 4.2 in a later check (n = 1 reversing at
``dt |u| / l = 10``, dt = 0.1); C = 8 is twice that. The median ratio is ~0.01: the
estimate is an upper bound, typical errors are 10 to 1000 times smaller. Against a
DOPRI5 reference at 1e-12 on fresh states (dt = 0.02 .. 0.2, ``dt |u| / l`` = 0.01 ..
100, tolerances 1e-3 .. 1e-8) the worst error was 0.53 times the tolerance;
tests/trailer_env/test_fidelity.py keeps checking it.

Cost at the default tolerance 1e-4 and the scenes' speeds (|u| <= 1.5 m/s) under
random actions: one substep for n <= 3 (rarely 2 at n = 3), 1.2 .. 1.5 on average at
n = 8, 2 .. 3 at n = 16, 3.4 .. 6.4 at n = 32 (the reversing scenes, whose convoys
fold and spin, take the most).

Integrators (see :func:`register_integrator` to add one):

* ``"rk4"``: :class:`dynamics.Stepper`, classical RK4 with the mass's quadratic
  motion evaluated exactly inside each step.
* ``"rk4-energy"``: the same with the energy-preserving rescaling. The energy is
  conserved only when the actuator does no work, so this needs ``mu = 0``
  (a passive convoy; the action then has no effect).
* ``"dopri5"``: :class:`dynamics.AdaptiveStepper`, Dormand-Prince 5(4) with its own
  per-environment step control (``rtol = atol = tolerance``, Hairer's RMS norm per
  internal step); ``substeps`` is ignored. Each environment's step size is carried
  from one control step to the next.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numba import njit

from dynamics import AdaptiveStepper, ConvoyParams, Stepper
from dynamics.adaptive import STATUS_OK
from dynamics.params import bounded_integer, bounded_real

#: (mtime, size) of this file when it was imported (see dynamics.jit.cached_njit).
SOURCE_STAMP = (os.stat(__file__).st_mtime, os.stat(__file__).st_size)

#: RK4's usable stability limit of ``dt r`` by number of trailers (linear interpolation
#: between entries, the last value beyond): the smaller of the default convoy's and a
#: trailer-dominated one's (a = 0.1, mu = 0), linearised at the straight convoy (a
#: perturbation must decay 1e4-fold without growing 100-fold, benchmarks/stability.py).
RK4_STABILITY_LIMITS: tuple[tuple[int, float], ...] = (
    (0, 2.785), (1, 2.785), (2, 2.734), (3, 2.586), (4, 2.458), (5, 2.347), (6, 2.251),
    (8, 2.098), (10, 1.973), (12, 1.880), (16, 1.761), (20, 1.705), (24, 1.692),
    (32, 1.594), (48, 1.538), (64, 1.497), (96, 1.463), (128, 1.446),
)  # fmt: skip
#: Fraction of the stability limit the auto rule may use: non-straight states have
#: eigenvalues up to ~2.4 times the straight convoy's rate ``r``.
STABILITY_FRACTION = 0.4
#: RK4's error constant C of the auto rule (see the module docstring).
ERROR_CONSTANT = 8.0
#: g(n) = CHAIN_GROWTH[0] + CHAIN_GROWTH[1] n.
CHAIN_GROWTH = (0.55, 0.15)
#: Weights of the mass's speed / s_max and sqrt(acceleration / s_max) in r_mass.
MASS_WEIGHTS = (0.1, 0.4)
#: Upper bound on the tolerance: the error model's calibrated range.
MAX_TOLERANCE = 1e-3
#: Lower bound on the tolerance (float64 rounding).
MIN_TOLERANCE = 1e-13
#: Substeps the stability bound may ask for, at most (dt |u| / l ~ 1e6).
HARD_MAX_SUBSTEPS = 1_000_000
#: Upper bound on fixed ``substeps``: 10,000 RK4 substeps of an
#: 8-trailer convoy take ~5 ms; 1e8 of them took 25 s per control step.
MAX_FIXED_SUBSTEPS = 10_000

# Indices into the packed settings of auto_substeps.
(
    AUTO_SPEED_RATE,
    AUTO_CHAIN,
    AUTO_MASS_SPEED,
    AUTO_MASS_ACCEL,
    AUTO_DT,
    AUTO_X_ONE,
    AUTO_SCALE,
    AUTO_INV_X_SAFE,
    AUTO_MAX_SUBSTEPS,
) = range(9)


class AccuracyWarning(UserWarning):
    """A step's estimated error exceeded the fidelity's tolerance (a substep cap bound)."""


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


class RK4Integrator(Stepper):
    """:class:`dynamics.Stepper` holding its NaN energy targets (the default, "at the start
    of each call") across calls: allocating them per call costs a single environment's
    step about 1.4 us of its ~7."""

    def __init__(
        self, params: ConvoyParams, *, with_pose: bool = False, preserve_energy: bool = False
    ) -> None:
        super().__init__(params, with_pose=with_pose, preserve_energy=preserve_energy)
        self._no_targets = np.full(0, np.nan)

    def step(
        self,
        z: np.ndarray,
        act: np.ndarray,
        dt: float,
        substeps: np.ndarray,
        target_energy: np.ndarray | None = None,
    ) -> None:
        """:meth:`dynamics.Stepper.step`."""
        if target_energy is None:
            if self._no_targets.shape[0] != z.shape[0]:
                self._no_targets = np.full(z.shape[0], np.nan)
            target_energy = self._no_targets
        super().step(z, act, dt, substeps, target_energy)


class AdaptiveIntegrator:
    """DOPRI5 behind the :class:`BatchIntegrator` interface (``substeps`` is ignored).

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


_INTEGRATORS: dict[str, IntegratorSpec] = {
    "rk4": IntegratorSpec(lambda params, with_pose, _: RK4Integrator(params, with_pose=with_pose)),
    "rk4-energy": IntegratorSpec(
        lambda params, with_pose, _: RK4Integrator(
            params, with_pose=with_pose, preserve_energy=True
        ),
        conserved_energy_only=True,
    ),
    "dopri5": IntegratorSpec(
        lambda params, with_pose, fidelity: AdaptiveIntegrator(
            params, with_pose, fidelity.tolerance
        ),
        uses_substeps=False,
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


def stability_limit(n_trailers: int) -> float:
    """RK4's usable stability limit of ``dt r`` with ``n_trailers`` (interpolated table)."""
    counts, limits = zip(*RK4_STABILITY_LIMITS, strict=True)
    return float(np.interp(n_trailers, counts, limits))


def chain_growth(n_trailers: int) -> float:
    """g(n), the factor on the convoy's rate in the error estimate."""
    return CHAIN_GROWTH[0] + CHAIN_GROWTH[1] * n_trailers


def cart_rate_coefficient(params: ConvoyParams, planar: bool) -> float:
    """Largest ``|M a + mu xi| / (I0 + mu xi^2)`` over the mass's positions ``xi``.

    The cart's eigenvalue at a straight convoy is this times ``|u|`` (the mass rides
    as part of the cart); rail modes hold ``xi = b``, planar mode lets ``xi`` range
    over ``b +- s_max`` (the extremes or the interior stationary points).
    """
    moment, inertia, mu = params.M * params.a, params.I0, params.mu

    def coefficient(xi: float) -> float:
        return abs(moment + mu * xi) / (inertia + mu * xi * xi)

    if not planar:
        return coefficient(params.b)
    low, high = params.b - params.s_max, params.b + params.s_max
    candidates = [low, high]
    if mu > 0.0:
        root = math.sqrt(moment * moment + mu * inertia)
        candidates += [x for x in ((-moment + root) / mu, (-moment - root) / mu) if low < x < high]
    return max(coefficient(xi) for xi in candidates)


@dataclass(frozen=True)
class Fidelity:
    """Integrator and step control of the environments' physics.

    Attributes:
        integrator: A registered name: "rk4" (default), "rk4-energy" (``mu = 0`` only)
            or "dopri5" (adaptive).
        substeps: An int in [1, 10_000] (:data:`MAX_FIXED_SUBSTEPS`), or "auto" (default)
            for the per-environment rule of the module docstring.
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
        return _INTEGRATORS[self.integrator].uses_substeps

    @property
    def auto(self) -> bool:
        """Whether substeps are chosen per environment and step."""
        return self.substeps == "auto" and _INTEGRATORS[self.integrator].uses_substeps

    @property
    def fixed_substeps(self) -> int:
        """The substep count when it is not chosen per step (1 for "auto" and adaptive)."""
        return self.substeps if isinstance(self.substeps, int) else 1

    @classmethod
    def coerce(cls, value: Fidelity | dict[str, Any] | str | int | None) -> Fidelity:
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

    def auto_settings(self, params: ConvoyParams, dt: float, planar: bool) -> np.ndarray:
        """The packed float64 settings :func:`auto_substeps` reads (see the module docstring)."""
        n = params.n_trailers
        speed_rate = max(1.0 / params.l, cart_rate_coefficient(params, planar))
        x_safe = STABILITY_FRACTION * stability_limit(n)
        settings = np.empty(9)
        settings[AUTO_SPEED_RATE] = speed_rate
        settings[AUTO_CHAIN] = chain_growth(n)
        settings[AUTO_MASS_SPEED] = MASS_WEIGHTS[0] / params.s_max
        settings[AUTO_MASS_ACCEL] = MASS_WEIGHTS[1] / math.sqrt(params.s_max)
        settings[AUTO_DT] = dt
        # One substep is accurate enough while C (dt R)^5 <= tolerance.
        settings[AUTO_X_ONE] = (self.tolerance / ERROR_CONSTANT) ** 0.2
        # k_acc = ceil(scale (dt R)^(5/4)).
        settings[AUTO_SCALE] = (ERROR_CONSTANT / self.tolerance) ** 0.25
        settings[AUTO_INV_X_SAFE] = 1.0 / x_safe
        settings[AUTO_MAX_SUBSTEPS] = self.max_substeps
        return settings


@njit(cache=True, nogil=True)
def auto_substeps_row(z: np.ndarray, act: np.ndarray, settings: np.ndarray, i: int) -> tuple:
    """The auto rule of the module docstring for row ``i``: (substeps, within tolerance).

    The second value is False when a cap (``max_substeps`` on the accuracy rule, or
    :data:`HARD_MAX_SUBSTEPS` on everything) keeps the count below what the error
    estimate asks for: the step's estimated error then exceeds the tolerance.
    """
    speed_rate = settings[AUTO_SPEED_RATE]
    dt = settings[AUTO_DT]
    x_plain = dt * max(abs(z[i, 0]) * speed_rate, abs(z[i, 1]))
    mass = settings[AUTO_MASS_SPEED] * (abs(act[i, 2]) + abs(act[i, 3])) + settings[
        AUTO_MASS_ACCEL
    ] * math.sqrt(abs(act[i, 4]) + abs(act[i, 5]))
    x = max(settings[AUTO_CHAIN] * x_plain, dt * mass)
    inv_x_safe = settings[AUTO_INV_X_SAFE]
    if x <= settings[AUTO_X_ONE] and x_plain * inv_x_safe <= 1.0:
        return 1, True  # the common case: no powers needed
    if not math.isfinite(x):
        return 1, True  # the environment reports the non-finite state
    wanted = np.ceil(settings[AUTO_SCALE] * x**1.25)
    accurate = min(wanted, settings[AUTO_MAX_SUBSTEPS])
    stable = np.ceil(x_plain * inv_x_safe)
    chosen = min(max(accurate, stable, 1.0), HARD_MAX_SUBSTEPS)
    return int(chosen), chosen >= wanted


@njit(cache=True)
def auto_substeps(z: np.ndarray, act: np.ndarray, settings: np.ndarray, out: np.ndarray) -> None:
    """The auto rule of the module docstring for every row: substep counts into ``out``.

    ``act`` must hold the accelerations of the step about to be taken; ``settings``
    comes from :meth:`Fidelity.auto_settings`.
    """
    for i in range(z.shape[0]):
        out[i], _ = auto_substeps_row(z, act, settings, i)
