"""Physical parameters of the convoy (physics.md section 1)."""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass


@dataclass(frozen=True)
class ConvoyParams:
    """Parameters of a cart pulling ``n_trailers`` identical trailers.

    Lengths in metres, masses in kilograms, inertias in kg m^2 (any consistent
    units work: the equations are dimensionally homogeneous).

    Attributes:
        n_trailers: Number of trailers n >= 0 (n = 0 is the Chaplygin sleigh).
        M: Mass of the cart, > 0.
        J0: Moment of inertia of the cart about its centre of mass, > 0.
        a: Distance from the cart's axle midpoint to its centre of mass along the
            heading (forward positive); any real.
        m: Mass of each trailer (centre of mass at its axle midpoint), > 0.
        J: Moment of inertia of each trailer about its axle midpoint, >= 0. A
            physical trailer has J < m l^2; larger values are accepted with a
            warning.
        l: Hitch rod length, > 0.
        mu: Moving point mass carried by the cart, >= 0 (0 = no actuator).
        b: Longitudinal position of the mass's lateral rail, measured from the
            cart's axle midpoint; any real.
        s_max: Half-length of the rail: the mass stays in abs(s) <= s_max, > 0.
    """

    n_trailers: int = 2
    M: float = 1.0
    J0: float = 0.2
    a: float = 0.5
    m: float = 1.0
    J: float = 0.1
    l: float = 1.0
    mu: float = 0.5
    b: float = 1.0
    s_max: float = 0.5

    def __post_init__(self) -> None:
        n = self.n_trailers
        if isinstance(n, bool) or not isinstance(n, int):
            if isinstance(n, float) and not isinstance(n, bool) and n.is_integer():
                object.__setattr__(self, "n_trailers", int(n))
            else:
                raise ValueError(f"n_trailers must be an integer >= 0, got {n!r}")
        if self.n_trailers < 0:
            raise ValueError(f"n_trailers must be >= 0, got {self.n_trailers}")
        for field in ("M", "J0", "a", "m", "J", "l", "mu", "b", "s_max"):
            value = getattr(self, field)
            try:
                as_float = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"{field} must be a real number, got {value!r}") from None
            if not math.isfinite(as_float):
                raise ValueError(f"{field} must be finite, got {value!r}")
            object.__setattr__(self, field, as_float)
        for field in ("M", "m", "J0", "l", "s_max"):
            if getattr(self, field) <= 0.0:
                raise ValueError(f"{field} must be > 0, got {getattr(self, field)!r}")
        for field in ("J", "mu"):
            if getattr(self, field) < 0.0:
                raise ValueError(f"{field} must be >= 0, got {getattr(self, field)!r}")
        if self.m * self.l**2 <= self.J:
            warnings.warn(
                f"J = {self.J} >= m*l**2 = {self.m * self.l**2}: allowed, but no physical "
                "trailer with its mass at the axle has it (thesis eq. 3.35)",
                UserWarning,
                stacklevel=3,
            )

    @property
    def I0(self) -> float:
        """Cart inertia about its axle midpoint, J0 + M a^2."""
        return self.J0 + self.M * self.a**2

    @property
    def n_state(self) -> int:
        """Length of the reduced state z = (u, omega, alpha_1..alpha_n)."""
        return self.n_trailers + 2

    def replace(self, **changes: float | int) -> ConvoyParams:
        """Return a copy with some fields changed (validated again).

        Raises:
            ValueError: If a name is not a field of ConvoyParams, or a value is invalid.
        """
        names = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(changes) - names)
        if unknown:
            raise ValueError(f"unknown ConvoyParams field(s) {unknown}; valid: {sorted(names)}")
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]
