"""Physical parameters of the convoy (physics.md section 1), and the input policy.

Input policy, shared by every public entry point of ``dynamics`` and ``trailer_env``
(:func:`real_number`, :func:`bounded_real`, :func:`bounded_integer`): a number must be
a real number (``int``, ``float``, numpy integers and floats); bools, strings,
complex numbers, None and containers are refused with a TypeError naming the
argument. A value of the right type that is out of range (NaN, inf, an int too
large for a float, a magnitude outside the documented physical range) is refused
with a ValueError naming the argument and the accepted range. OverflowError never
escapes.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import operator
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

#: Largest number of trailers. The kernels are O(n) per row, but RK4's stability limit
#: was measured up to n = 128 (trailer_env.substeps.RK4_STABILITY_LIMITS) and the
#: substep rule's chain factor grows with n; 256 leaves room without extrapolating far.
MAX_TRAILERS = 256
#: Accepted range of the lengths l and s_max (m), and bound on |a| and |b|. Every
#: length and mass lies within [1e-6, 1e6] of SI: a micro-robot to a road train and
#: beyond, while products such as M a^2 or the energy stay far from float64's limits
#: (1e308) and quotients such as J / l^2 far from its resolution.
LENGTH_RANGE = (1e-6, 1e6)
#: Accepted range of the masses M and m (kg); mu lies in [0, MASS_RANGE[1]].
MASS_RANGE = (1e-6, 1e6)
#: Accepted range of J0 (kg m^2), a mass times a length squared; J lies in [0, 1e18].
INERTIA_RANGE = (1e-18, 1e18)
#: Largest J / (m l^2). A physical trailer (its mass at the axle) has J < m l^2; up to
#: 100 times that is accepted with a warning. Beyond, the hitch dynamics turn so stiff
#: that RK4's substep rule no longer keeps a step stable (measured: J = 1e4 m l^2 with
#: l = 1e-4 m diverged in Coast-v0; 1e3 m l^2 still integrated).
MAX_TRAILER_INERTIA_RATIO = 100.0
#: Largest ratio between two masses (M / m, m / M, mu / M) and between another length
#: and l (|a| / l, |b| / l, s_max / l). Within each field's own range, extreme ratios
#: still make one part of the convoy a reservoir the rest cannot absorb: a cart with
#: I0 = 1e18 m l^2 turning at 0.02 rad/s threw its two trailers to 1e63 m/s in one step.
MAX_RATIO = 1e3
#: Accepted range of J0 / (M l^2), the cart's own inertia relative to its mass and the
#: rod length.
CART_INERTIA_RATIO_RANGE = (1e-6, 1e6)


def real_number(name: str, value: object) -> float:
    """``value`` as a finite float.

    Raises:
        TypeError: If ``value`` is not a real number (bools, strings, complex, None ...).
        ValueError: If it is NaN, infinite or too large for a float.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__} {value!r}")
    try:
        number = float(value)
    except OverflowError:
        raise ValueError(f"{name} must be finite, got an integer too large for a float") from None
    if not math.isfinite(number):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return number


def bounded_real(
    name: str,
    value: object,
    low: float,
    high: float,
    *,
    low_open: bool = False,
    high_open: bool = False,
) -> float:
    """``value`` as a float in ``[low, high]`` (an end excluded with ``low_open``, ``high_open``).

    Raises:
        TypeError: If ``value`` is not a real number.
        ValueError: If it is not finite or out of range; the message gives the range.
    """
    interval = f"{'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"
    too_large = isinstance(value, numbers.Integral) and abs(int(value)) > 10**300
    if too_large and not isinstance(value, bool):  # float() would overflow
        raise ValueError(f"{name} must be in {interval}, got an integer too large for a float")
    number = real_number(name, value)
    below = number <= low if low_open else number < low
    above = number >= high if high_open else number > high
    if below or above:
        raise ValueError(f"{name} must be in {interval}, got {value!r}")
    return number


def bounded_integer(name: str, value: object, low: int, high: int) -> int:
    """``value`` as an int in ``[low, high]``; an integral float (3.0) is accepted.

    Raises:
        TypeError: If ``value`` is not a real number (bools and strings included).
        ValueError: If it is not integral or out of range; the message gives the range.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__} {value!r}")
    if isinstance(value, numbers.Integral):
        integer = operator.index(value)
    else:
        number = float(value)
        if not number.is_integer():
            raise ValueError(f"{name} must be an integer in [{low}, {high}], got {value!r}")
        integer = int(number)
    if not low <= integer <= high:
        digits = len(str(abs(integer)))
        shown = repr(value) if digits < 30 else f"an integer of {digits} digits"
        raise ValueError(f"{name} must be an integer in [{low}, {high}], got {shown}")
    return integer


def one_of(name: str, value: object, choices: Sequence[str], *, none: bool = False) -> None:
    """Check that ``value`` is one of the strings ``choices`` (or None, with ``none``).

    Raises:
        TypeError: If it is not a str (nor None where allowed), naming the choices.
        ValueError: If it is another str, naming the choices.
    """
    if value is None and none:
        return
    allowed = f"None or one of {tuple(choices)}" if none else f"one of {tuple(choices)}"
    if not isinstance(value, str):
        raise TypeError(f"{name} must be {allowed}, got {type(value).__name__} {value!r}")
    if value not in choices:
        raise ValueError(f"{name} must be {allowed}, got {value!r}")


@dataclass(frozen=True)
class ConvoyParams:
    """Parameters of a cart pulling ``n_trailers`` identical trailers.

    Lengths in metres, masses in kilograms, inertias in kg m^2 (the equations are
    dimensionally homogeneous, but the accepted ranges below are stated in SI).
    Every field follows the input policy of the module docstring: a bool, string or
    other non-number is a TypeError, an out-of-range value a ValueError naming the
    field and its range. The ranges (:data:`LENGTH_RANGE`, :data:`MASS_RANGE`,
    :data:`INERTIA_RANGE`, :data:`MAX_TRAILERS`) keep every derived quantity finite;
    the ratios are bounded too, so that no part of the convoy dwarfs another: M / m,
    m / M, mu / M, |a| / l, |b| / l and s_max / l at most 1e3 (:data:`MAX_RATIO`),
    J0 / (M l^2) in [1e-6, 1e6] and J <= 100 m l^2.

    Attributes:
        n_trailers: Number of trailers, an integer in [0, 256] (n = 0 is the Chaplygin
            sleigh); an integral float such as 3.0 is accepted.
        M: Mass of the cart, in [1e-6, 1e6].
        J0: Moment of inertia of the cart about its centre of mass, in [1e-18, 1e18].
        a: Distance from the cart's axle midpoint to its centre of mass along the
            heading (forward positive), in [-1e6, 1e6].
        m: Mass of each trailer (centre of mass at its axle midpoint), in [1e-6, 1e6].
        J: Moment of inertia of each trailer about its axle midpoint, in [0, 1e18]
            and at most 100 m l^2 (:data:`MAX_TRAILER_INERTIA_RATIO`). A physical
            trailer has J < m l^2; larger values are accepted with a warning.
        l: Hitch rod length, in [1e-6, 1e6].
        mu: Moving point mass carried by the cart, in [0, 1e6] (0 = no actuator).
        b: Longitudinal position of the mass's lateral rail, measured from the
            cart's axle midpoint, in [-1e6, 1e6].
        s_max: Half-length of the rail: the mass stays in abs(s) <= s_max; in [1e-6, 1e6].
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
        object.__setattr__(
            self, "n_trailers", bounded_integer("n_trailers", self.n_trailers, 0, MAX_TRAILERS)
        )
        length_low, length_high = LENGTH_RANGE
        mass_low, mass_high = MASS_RANGE
        inertia_low, inertia_high = INERTIA_RANGE
        ranges = {
            "M": (mass_low, mass_high),
            "J0": (inertia_low, inertia_high),
            "a": (-length_high, length_high),
            "m": (mass_low, mass_high),
            "J": (0.0, inertia_high),
            "l": (length_low, length_high),
            "mu": (0.0, mass_high),
            "b": (-length_high, length_high),
            "s_max": (length_low, length_high),
        }
        for field, (low, high) in ranges.items():
            object.__setattr__(self, field, bounded_real(field, getattr(self, field), low, high))
        self._check_ratios()
        if MAX_TRAILER_INERTIA_RATIO * self.m * self.l**2 < self.J:
            raise ValueError(
                f"J = {self.J:g} exceeds {MAX_TRAILER_INERTIA_RATIO:g} m l**2 = "
                f"{MAX_TRAILER_INERTIA_RATIO * self.m * self.l**2:g} (m = {self.m:g}, "
                f"l = {self.l:g}): a trailer's inertia about its axle is below m l**2"
            )
        if self.m * self.l**2 <= self.J:
            warnings.warn(
                f"J = {self.J} >= m*l**2 = {self.m * self.l**2}: allowed, but no physical "
                "trailer with its mass at the axle has it (thesis eq. 3.35)",
                UserWarning,
                stacklevel=3,
            )

    def _check_ratios(self) -> None:
        """Refuse ratios beyond :data:`MAX_RATIO` and :data:`CART_INERTIA_RATIO_RANGE`."""
        ratios = (
            ("M / m", self.M / self.m, f"M = {self.M:g}, m = {self.m:g}"),
            ("m / M", self.m / self.M, f"m = {self.m:g}, M = {self.M:g}"),
            ("mu / M", self.mu / self.M, f"mu = {self.mu:g}, M = {self.M:g}"),
            ("|a| / l", abs(self.a) / self.l, f"a = {self.a:g}, l = {self.l:g}"),
            ("|b| / l", abs(self.b) / self.l, f"b = {self.b:g}, l = {self.l:g}"),
            ("s_max / l", self.s_max / self.l, f"s_max = {self.s_max:g}, l = {self.l:g}"),
        )
        for label, ratio, values in ratios:
            if ratio > MAX_RATIO:
                raise ValueError(
                    f"{label} = {ratio:.3g} exceeds {MAX_RATIO:g} ({values}): the convoy's "
                    "parts must be of comparable size"
                )
        low, high = CART_INERTIA_RATIO_RANGE
        ratio = self.J0 / (self.M * self.l**2)
        if not low <= ratio <= high:
            raise ValueError(
                f"J0 / (M l**2) = {ratio:.3g} is outside [{low:g}, {high:g}] (J0 = {self.J0:g}, "
                f"M = {self.M:g}, l = {self.l:g})"
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
            TypeError: If a name is not a field of ConvoyParams, or a value is not a number.
            ValueError: If a value is out of range.
        """
        names = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(changes) - names)
        if unknown:
            raise TypeError(f"unknown ConvoyParams field(s) {unknown}; valid: {sorted(names)}")
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]
