"""The fixed-step methods of ``python -m benchmarks.stability`` and their linear stability
theory: each method's stability function R(z) and its real-axis limit (shared by the
measurements and the charts)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.optimize import brentq

from dynamics.adaptive import DP_A, DP_B

RK4 = "RK4"
RK4_ENERGY_PRESERVING = "RK4 energy-preserving"
DOPRI5_FIXED = "DOPRI5 fixed step"
METHODS = (RK4, RK4_ENERGY_PRESERVING, DOPRI5_FIXED)
"""The fixed-step methods compared; the names label the CSV rows and the charts."""


def rk4_stability(z: complex) -> complex:
    """Stability function of classical RK4."""
    return 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24


def dopri5_stability(z: complex) -> complex:
    """Stability function of DOPRI5's propagated (5th-order) solution, from its tableau."""
    stages = 6  # stage 7 only feeds the error estimate
    matrix = np.eye(stages) - z * DP_A[:stages, :stages]
    return complex(1 + z * DP_B[:stages] @ np.linalg.solve(matrix, np.ones(stages)))


def stability_function(method: str) -> Callable[[complex], complex]:
    """R(z) of a method (the energy-preserving step has RK4's)."""
    return dopri5_stability if method == DOPRI5_FIXED else rk4_stability


def real_axis_limit(method: str) -> float:
    """x* > 0 with |R(-x)| < 1 on (0, x*) and |R(-x*)| = 1."""
    function = stability_function(method)
    return float(brentq(lambda x: abs(function(-x)) - 1.0, 1.5, 4.0, xtol=1e-13))
