"""Exact reduced nonholonomic dynamics of a cart pulling n trailers, free of any RL import.

See ``docs/physics.md`` for the model. The public API:

* :class:`ConvoyParams`: the physical parameters (frozen, validated).
* :func:`rhs`, :func:`rhs_planar`: dz/dt for z = (u, omega, alpha_1..alpha_n),
  batched, with the moving mass on the lateral rail or at a prescribed planar position.
* :func:`energy`, :func:`energy_planar`, :func:`inertia_R`.
* :func:`step_rk4`, :func:`step_rk4_planar`, :func:`simulate`, :class:`Stepper`: fixed-step RK4
  over batches, optionally energy-preserving.
* :func:`integrate_adaptive`, :class:`AdaptiveStepper`: Dormand-Prince 5(4), per-row error control.
* :func:`body_poses`: the plane poses of every body.
* :func:`singular_margin`, :func:`is_jackknifed`, :func:`nonholonomy_degree`.
* :mod:`dynamics.analysis`: energy tori, equilibria, relative equilibria, the n = 1, a = 0 case.
"""

from dynamics import _notice  # noqa: F401  (the first-compile notice, on stderr)
from dynamics.adaptive import AdaptiveResult, AdaptiveStats, AdaptiveStepper, integrate_adaptive
from dynamics.integrate import Stepper, Trajectory, simulate, step_rk4, step_rk4_planar
from dynamics.model import energy, energy_planar, inertia_R, rhs, rhs_planar
from dynamics.nonholonomy import NonholonomyDegree, nonholonomy_degree
from dynamics.params import ConvoyParams
from dynamics.plane import body_poses
from dynamics.singular import is_jackknifed, singular_margin

__all__ = [
    "AdaptiveResult",
    "AdaptiveStats",
    "AdaptiveStepper",
    "ConvoyParams",
    "NonholonomyDegree",
    "Stepper",
    "Trajectory",
    "body_poses",
    "energy",
    "energy_planar",
    "inertia_R",
    "integrate_adaptive",
    "is_jackknifed",
    "nonholonomy_degree",
    "rhs",
    "rhs_planar",
    "simulate",
    "singular_margin",
    "step_rk4",
    "step_rk4_planar",
]
