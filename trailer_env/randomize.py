"""Randomised physics and starts: per-episode factors on the nominal parameters.

``gym.make(id, randomize=...)`` (and the native vector env and the SB3 adapter, which
take the same keywords) draws, at every reset, one factor per randomised quantity,
uniformly in its range, from the environment's own generator, right after the
episode's start:

* ``"M"``, ``"J0"``, ``"a"``, ``"m"``, ``"J"``, ``"l"``, ``"mu"``: the episode's
  :class:`dynamics.ConvoyParams` field is ``nominal * factor`` (the nominal value is
  the settings', e.g. ``gym.make(..., mu=0.4)``'s 0.4);
* ``"speed"``: the start's forward speed ``u`` (as the scene drew it) is multiplied by
  the factor; the turning rate, the hitch angles and the mass are left as drawn, so a
  scene's starting speed range ``U(lo, hi)`` becomes ``factor * U(lo, hi)``.

``randomize`` is a dict of ranges ``{"M": (0.8, 1.2), "mu": (0.9, 1.1), ...}``
(factors of the nominal value; a list ``[0.8, 1.2]`` works too, as JSON gives it), or a
preset name of :data:`PRESETS`. The actuator's geometry (``b``, ``s_max``) is never
randomised: the observation's scaling and the rail guard depend on it.

Order of the draws: per reset, the scene's start, then one ``Generator.uniform(lo,
hi)`` per randomised quantity in the order of :data:`NAMES` (skipping those not
randomised). With ``randomize=None`` nothing is drawn: every stream and start is what
it was without the option. The draws run in compiled code (:func:`draw_factors`) with
NumPy's algorithm, so a vector env seeded ``s`` replays single envs seeded ``s + i``.

Which parameters matter, measured with the LQR on Reverse-v1: docs/physics.md, section
"Parameter mismatch" (``mu`` and ``a`` most, then ``J0``, ``M``, ``l``; ``m`` and ``J``
change nothing measurable): the presets randomise those that matter.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from dynamics.columns import U
from dynamics.jit import cached_njit
from trailer_env.substeps import AUTO_LENGTH, AUTO_SPEED_RATE, cart_rate

#: The physical parameters that may be randomised, in the packed order of
#: :func:`dynamics.jit.pack_params` (column ``k`` of the per-row parameters).
PARAMETERS: tuple[str, ...] = ("M", "J0", "a", "m", "J", "l", "mu")
#: Every randomisable quantity, in the order of the draws: the parameters, then the speed.
NAMES: tuple[str, ...] = (*PARAMETERS, "speed")
#: Column of the speed factor in the factor arrays.
SPEED = len(PARAMETERS)
_M, _J0, _A, _L, _MU = (PARAMETERS.index(name) for name in ("M", "J0", "a", "l", "mu"))
#: Accepted factors: (0, MAX_FACTOR]. Beyond the parameters' own ranges
#: (:class:`dynamics.ConvoyParams`) a factor is refused anyway; this bounds the speed's.
MAX_FACTOR = 1e3

_MATTER = ("M", "J0", "a", "l", "mu")
#: Named presets: +-10, 20, 30 and 40 % on the parameters that change the LQR's results on
#: Reverse-v1 (docs/physics.md, "Parameter mismatch"); ``m`` and ``J`` do not. A preset
#: applies to every scene: one whose formulas hold a parameter fixed (Dock-v0's ``l``,
#: ``ConvoyCore.fixed_parameters``) varies the others (:meth:`Randomization.without`);
#: a dict of ranges that names such a parameter is refused there.
PRESETS: dict[str, dict[str, tuple[float, float]]] = {
    f"mismatch{size}": {name: (1.0 - size / 100, 1.0 + size / 100) for name in _MATTER}
    for size in (10, 20, 30, 40)
}


@dataclass(frozen=True)
class Randomization:
    """Validated ranges of the factors (see the module docstring).

    Attributes:
        ranges: ``(name, low, high)`` per randomised quantity, in the order of :data:`NAMES`.
        preset: The preset's name when it came from one (:data:`PRESETS`), else None.
    """

    ranges: tuple[tuple[str, float, float], ...]
    preset: str | None = field(default=None, compare=False)

    @classmethod
    def coerce(cls, value: object) -> Randomization | None:
        """A Randomization from None, itself, a preset name or a dict of ranges.

        Raises:
            TypeError: If ``value`` is not one of those, a range is not a pair of real
                numbers, or a name is not a str.
            ValueError: On an unknown preset or name (listing the valid ones), an empty
                dict, a non-finite or non-positive factor, a factor above 1e3, or
                ``low > high``; the message names the quantity.
        """
        if value is None or isinstance(value, Randomization):
            return value
        if isinstance(value, str):
            if value not in PRESETS:
                raise ValueError(
                    f"randomize: unknown preset {value!r}; presets: {sorted(PRESETS)}, or a "
                    f"dict of factor ranges over {list(NAMES)}"
                )
            table = PRESETS[value]
            return cls(tuple((name, *table[name]) for name in NAMES if name in table), value)
        if not isinstance(value, Mapping):
            raise TypeError(
                "randomize must be None, a preset name or a dict of factor ranges such as "
                f"{{'M': (0.8, 1.2)}}, got {type(value).__name__} {value!r}"
            )
        if not value:
            raise ValueError(
                "randomize: the dict of ranges is empty; use None for no randomisation"
            )
        for name in value:
            if not isinstance(name, str):
                raise TypeError(f"randomize: names must be str, got {type(name).__name__} {name!r}")
        unknown = sorted(set(value) - set(NAMES))
        if unknown:
            raise ValueError(
                f"randomize: unknown name(s) {unknown}; valid: {list(NAMES)} (b and s_max, the "
                "actuator's geometry, are not randomised)"
            )
        ranges = tuple((name, *_factor_range(name, value[name])) for name in NAMES if name in value)
        return cls(ranges)

    def without(self, names: Sequence[str]) -> Randomization | None:
        """The same ranges but for ``names`` (None when nothing is left); the draws of the
        others keep their order."""
        ranges = tuple(entry for entry in self.ranges if entry[0] not in names)
        return Randomization(ranges, preset=self.preset) if ranges else None

    @property
    def names(self) -> tuple[str, ...]:
        """The randomised quantities, in the order of the draws."""
        return tuple(name for name, _, _ in self.ranges)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lowest and highest factors per column of :data:`NAMES` (1 where not randomised)."""
        low = np.ones(len(NAMES))
        high = np.ones(len(NAMES))
        for name, lo, hi in self.ranges:
            low[NAMES.index(name)] = lo
            high[NAMES.index(name)] = hi
        return low, high

    def drawn_columns(self) -> np.ndarray:
        """Columns of :data:`NAMES` drawn at each reset, in the order of the draws (int64)."""
        return np.array([NAMES.index(name) for name in self.names], dtype=np.int64)

    def corners(self) -> list[dict[str, float]]:
        """Every corner of the box of parameter factors (the speed left out), as overrides."""
        names = [(name, lo, hi) for name, lo, hi in self.ranges if name != "speed"]
        corners: list[dict[str, float]] = [{}]
        for name, lo, hi in names:
            corners = [{**corner, name: factor} for corner in corners for factor in {lo, hi}]
        return corners


def _factor_range(name: str, value: object) -> tuple[float, float]:
    """``value`` as a (low, high) pair of factors for ``name``, or a clear error."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or len(value) != 2:
        raise TypeError(
            f"randomize[{name!r}] must be a (low, high) pair of factors, got "
            f"{type(value).__name__} {value!r}"
        )
    pair = []
    for end, bound in zip(("low", "high"), value, strict=True):
        if isinstance(bound, bool) or not isinstance(bound, numbers.Real):
            raise TypeError(
                f"randomize[{name!r}] {end} must be a real number, got {type(bound).__name__} "
                f"{bound!r}"
            )
        factor = float(bound)
        if not math.isfinite(factor) or not 0.0 < factor <= MAX_FACTOR:
            raise ValueError(
                f"randomize[{name!r}] {end} = {bound!r}: factors must be in (0, {MAX_FACTOR:g}]"
            )
        pair.append(factor)
    low, high = pair
    if low > high:
        raise ValueError(f"randomize[{name!r}] = ({low:g}, {high:g}): low > high")
    return low, high


def checked_observe_params(value: object) -> bool:
    """``observe_params`` as a bool.

    Raises:
        TypeError: If it is not a bool.
    """
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"observe_params must be a bool, got {type(value).__name__} {value!r}")
    return bool(value)


@cached_njit()
def draw_factors(
    generators: Sequence[np.random.Generator],
    picks: np.ndarray,
    rows: np.ndarray,
    columns: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    factors: np.ndarray,
) -> None:
    """Row ``rows[j]``'s factors from ``generators[picks[j]]``: one ``uniform(low[c],
    high[c])`` per column ``c`` of ``columns``, in order, into ``factors[rows[j], c]``
    (NumPy's draws to the bit; the other columns are left as they are)."""
    for j in range(rows.size):
        rng = generators[picks[j]]
        i = rows[j]
        for c in columns:
            factors[i, c] = rng.uniform(low[c], high[c])


@cached_njit()
def apply_factors(
    rows: np.ndarray,
    factors: np.ndarray,
    nominal: np.ndarray,
    pv: np.ndarray,
    nominal_auto: np.ndarray,
    auto: np.ndarray,
    b: float,
    s_max: float,
    planar: bool,
    z: np.ndarray,
) -> None:
    """The episode's parameters of ``rows``: ``pv[i] = nominal * factors[i, :P]``, the auto
    rule's settings recomputed from them (exactly as
    :func:`trailer_env.substeps.auto_settings` computes them for fixed parameters), and the
    start's speed ``z[i, U]`` scaled by the speed factor."""
    count = nominal.size
    for i in rows:
        for k in range(count):
            pv[i, k] = nominal[k] * factors[i, k]
        _row_auto(i, pv, nominal_auto, auto, b, s_max, planar)
        z[i, U] = z[i, U] * factors[i, count]


@cached_njit()
def _row_auto(
    i: int,
    pv: np.ndarray,
    nominal_auto: np.ndarray,
    auto: np.ndarray,
    b: float,
    s_max: float,
    planar: bool,
) -> None:
    """Row ``i``'s auto rule settings from its parameters ``pv[i]``."""
    for k in range(nominal_auto.size):
        auto[i, k] = nominal_auto[k]
    length = pv[i, _L]
    rate = cart_rate(pv[i, _M], pv[i, _J0], pv[i, _A], pv[i, _MU], b, s_max, planar)
    auto[i, AUTO_SPEED_RATE] = max(1.0 / length, rate)
    auto[i, AUTO_LENGTH] = length


@cached_njit()
def apply_params(
    rows: np.ndarray,
    values: np.ndarray,
    pv: np.ndarray,
    nominal_auto: np.ndarray,
    auto: np.ndarray,
    b: float,
    s_max: float,
    planar: bool,
) -> None:
    """Given parameters of ``rows``: ``pv[rows[j]] = values[j]`` and the auto rule's
    settings recomputed from them (as :func:`apply_factors` does)."""
    for j in range(rows.size):
        i = rows[j]
        for k in range(pv.shape[1]):
            pv[i, k] = values[j, k]
        _row_auto(i, pv, nominal_auto, auto, b, s_max, planar)
