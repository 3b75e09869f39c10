"""Degree of nonholonomy of the convoy's constraint distribution (physics.md section 10).

The configuration space has coordinates ``(x, y, theta, alpha_1..alpha_n)`` and the
admissible velocities are spanned by

* ``Z1 = cos(theta) d/dx + sin(theta) d/dy + sum_k A_k(alpha) d/dalpha_k`` (the cart rolls),
* ``Z2 = d/dtheta + d/dalpha_1`` (the cart turns; ``Z2 = d/dtheta`` when n = 0),

with the ``A_k`` of physics.md section 3 and ``l = 1`` (rescaling ``l`` rescales ``Z1`` and
leaves every span unchanged). ``D^k`` is the span at the point of all Lie brackets of
``Z1, Z2`` of length ``<= k``; the growth vector lists ``dim D^1, dim D^2, ...`` up to the
first ``k``, the degree of nonholonomy, at which it is the whole tangent space (``n + 3``).

Method: the brackets are computed, level by level, on truncated Taylor jets at the point
and in exact arithmetic.

1. *SE(2) reduction.* Both fields are invariant under rotations and translations of the
   plane, so every bracket ``B`` has the form ``B^x + i B^y = exp(i theta) g_B(alpha)``,
   ``B^theta = p_B(alpha)``, ``B^alpha = h_B(alpha)``. A field is stored as the ``n + 3``
   real functions ``(Re g, Im g, p, h_1..h_n)`` of the hitch angles alone; at the point the
   true vector is this one with its first two components rotated by ``theta``, which
   changes no rank. Written out in this form, ``[X, Y] = DY X - DX Y`` gives, with
   ``Z1 = (1, 0, A)``, ``Z2 = (0, 1, e_1)`` (``e_1`` the first unit vector),

   * ``[Z2, B] = (i g + dg/dalpha_1, dp/dalpha_1, dh/dalpha_1)``,
   * ``[Z1, B] = (A.grad g - i p, A.grad p, A.grad h - (DA) h)``.

2. *Jets.* Each function is replaced by its partial derivatives at the point up to some
   total order. A bracket of length ``L`` feeds at most ``K - L`` more differentiations
   before the last level ``K``, so it is carried to order ``K - L``: the tensors shrink
   as the brackets lengthen. Every ``A_k`` and each of its partials is a sum of products
   of ``sin``/``cos`` of single angles, so multiplying a jet by it is a sequence of
   one-dimensional Leibniz convolutions, each along one axis.
3. *Spans.* The brackets of length ``L`` span the same space as ``[Z_i, B]`` over
   ``i = 1, 2`` and ``B`` in a basis of the span of the brackets of length ``L - 1``
   (right-normed brackets span, by the Jacobi identity; the bracket is R-bilinear), so
   each level is replaced by a basis of its span before it is bracketed again: at most 16
   fields per level for n = 4 and 95 for n = 5, where the 2^(L-1) right-normed brackets
   would number thousands.
4. *Exact arithmetic.* Floating point cannot decide these ranks: the jets of long
   brackets span a range of magnitudes far wider than its precision, and their spans
   have singular values all the way down to rounding. The coefficients are polynomials in
   ``sin(alpha_k), cos(alpha_k)`` with integer coefficients, so each angle is replaced by
   an exact rational point of the unit circle (``tan(alpha/2)`` is a binary fraction),
   every sine or cosine within ``rtol`` of 0 is read as exactly 0 (floating point cannot
   hold ``cos(pi/2) = 0``), and all the linear algebra is done modulo a prime near 2^26.
   A rank modulo p never exceeds the rank over the rationals and equals it unless p
   divides one particular minor, so the computation is repeated with a second prime and
   the larger dimension is kept at each level.

The highest level ``K`` needed is not known in advance: ``n + 2`` (the regular value) is
tried first, then depths growing by half up to the Fibonacci bound ``F_{n+3}`` (Luca-Risler;
Jean 1996), and beyond it only if ``max_level`` asks.

Values computed with it (and, for n <= 4, by an independent symbolic computation in
``tests/dynamics/test_nonholonomy.py``, which lists every growth vector): degree ``n + 2``
at regular points; ``2n + 2 - k`` when ``cos(alpha_k) = 0`` for one ``k <= n - 1`` only;
``F_{n+3}`` (5, 8, 13, 21 for n = 2..5) when every ``alpha_k``, ``k <= n - 1``, is
``pi/2``. One call takes under 0.2 s for n <= 4 and up to about 10 s for n = 5.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from functools import cache, lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

IntArray = NDArray[np.int64]

__all__ = ["NonholonomyDegree", "fibonacci", "nonholonomy_degree"]

# Two primes below 2^26: a product of two residues is < 2^52, so an int64 sum of up to
# 2^11 such products cannot overflow. Sums over jet orders stay shorter because
# max_level is capped; matrix products are cut into chunks of that length.
_PRIMES = (67108859, 67108837)
_MAX_TERMS_PER_SUM = 2**11

# Components of a reduced field: the planar part g = Re + i Im, then theta, then alphas.
_RE, _IM, _THETA, _ALPHA0 = 0, 1, 2, 3


@dataclass(frozen=True)
class NonholonomyDegree:
    """Degree of nonholonomy at one configuration.

    Attributes:
        degree: Smallest ``k`` with ``dim D^k = n + 3``.
        growth_vector: ``(dim D^1, ..., dim D^degree)``; the last entry is ``n + 3``.
    """

    degree: int
    growth_vector: tuple[int, ...]


def fibonacci(k: int) -> int:
    """Return the Fibonacci number ``F_k`` with ``F_1 = F_2 = 1``.

    ``F_{n+3}`` bounds the degree of nonholonomy of the n-trailer system.

    Args:
        k: Index, ``k >= 1``.

    Returns:
        ``F_k``.

    Raises:
        ValueError: If ``k < 1``.
    """
    if k < 1:
        raise ValueError(f"Fibonacci index must be >= 1, got {k}")
    previous, current = 0, 1
    for _ in range(k - 1):
        previous, current = current, previous + current
    return current


def nonholonomy_degree(
    n: int,
    config: ArrayLike,
    *,
    max_level: int | None = None,
    rtol: float = 1e-9,
) -> NonholonomyDegree:
    """Compute the degree of nonholonomy and the growth vector at a configuration.

    The Lie brackets are computed, not looked up (see the module docstring for how).
    Regular configurations give degree ``n + 2`` and growth ``(2, 3, ..., n + 3)``;
    configurations with ``cos(alpha_k) = 0`` for some ``k <= n - 1`` give more.

    Args:
        n: Number of trailers, ``n >= 0``.
        config: The hitch angles ``(alpha_1..alpha_n)``, or a full configuration
            ``(x, y, theta, alpha_1..alpha_n)`` of length ``n + 3`` (``x, y, theta`` do not
            matter by SE(2) invariance).
        max_level: Longest brackets tried, at most 2048; defaults to the Fibonacci bound
            ``F_{n+3}``.
        rtol: A sine or cosine of a hitch angle smaller than this in absolute value is
            taken as exactly 0, i.e. angles within about ``rtol`` of a multiple of
            ``pi/2`` are taken as that multiple. Everything else is exact.

    Returns:
        The degree and the growth vector.

    Raises:
        ValueError: If ``n``, ``config``, ``max_level`` or ``rtol`` is invalid.
        RuntimeError: If full rank is not reached with brackets of length ``max_level``.

    Example:
        >>> nonholonomy_degree(2, [0.3, -0.2])
        NonholonomyDegree(degree=4, growth_vector=(2, 3, 4, 5))
        >>> nonholonomy_degree(2, [np.pi / 2, 0.4]).growth_vector
        (2, 3, 4, 4, 5)
    """
    n = _checked_integer("n", n, minimum=0)
    alphas = _checked_hitch_angles(n, config)
    highest = (
        fibonacci(n + 3)
        if max_level is None
        else _checked_integer("max_level", max_level, minimum=1, maximum=_MAX_TERMS_PER_SUM)
    )
    if (
        isinstance(rtol, bool)
        or not isinstance(rtol, (int, float, np.floating))
        or not 0.0 < rtol < 1.0  # also rejects NaN
    ):
        raise ValueError(f"rtol must be a number in (0, 1), got {rtol!r}")
    circle_points = [_rational_circle_point(float(alpha), float(rtol)) for alpha in alphas]

    for top_level in _jet_depths(n, highest):
        growth = _growth_vector_any_prime(circle_points, top_level)
        if growth[-1] == n + 3:
            return NonholonomyDegree(degree=len(growth), growth_vector=tuple(growth))
    raise RuntimeError(
        f"brackets of length <= max_level={highest} do not span the {n + 3}-dimensional "
        f"tangent space at alpha={alphas.tolist()}; raise max_level"
    )


# --- validation -----------------------------------------------------------------------


def _checked_integer(name: str, value: object, *, minimum: int, maximum: int | None = None) -> int:
    # bool is an int subclass, but n=True is surely a mistake.
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    if maximum is not None and value > maximum:
        raise ValueError(f"{name} must be <= {maximum}, got {value!r}")
    return int(value)


def _checked_hitch_angles(n: int, config: ArrayLike) -> NDArray[np.float64]:
    try:
        array = np.asarray(config, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(f"config must be an array of real numbers: {error}") from None
    if array.ndim != 1 or array.shape[0] not in (n, n + 3):
        raise ValueError(
            f"config must have shape ({n},) (the hitch angles) or ({n + 3},) "
            f"(x, y, theta, alphas) for n={n}, got shape {array.shape}"
        )
    if not np.all(np.isfinite(array)):
        raise ValueError("config contains non-finite values (NaN or inf)")
    return array[array.shape[0] - n :].copy()


def _jet_depths(n: int, highest: int) -> list[int]:
    """Increasing bracket depths to try, each about 1.5 times the last.

    The regular value ``n + 2`` comes first and the Fibonacci bound is never skipped.
    Deep jets are costly (the jets of the first levels have ``C(K + n - 1, n)`` entries),
    so most singular points, whose degree lies well below the bound, are settled early;
    restarting from scratch at most doubles the work of the last depth.
    """
    bound = fibonacci(n + 3)
    depths = [min(n + 2, highest)]
    while depths[-1] < highest:
        candidate = depths[-1] + max(1, depths[-1] // 2)
        if depths[-1] < bound:
            candidate = min(candidate, bound)
        depths.append(min(candidate, highest))
    return depths


# --- exact arithmetic -----------------------------------------------------------------


def _rational_circle_point(alpha: float, zero_tolerance: float) -> tuple[Fraction, Fraction]:
    """An exact ``(sin, cos)`` on the unit circle next to ``alpha``.

    Built from the half-angle tangent, a binary fraction, so that sin^2 + cos^2 = 1 holds
    exactly and the exact computation is that of a true configuration of the convoy.
    """
    sine, cosine = math.sin(alpha), math.cos(alpha)
    if abs(cosine) <= zero_tolerance:
        return Fraction(1 if sine > 0 else -1), Fraction(0)
    if abs(sine) <= zero_tolerance:
        return Fraction(0), Fraction(1 if cosine > 0 else -1)
    # tan(alpha/2) in whichever form does not cancel.
    half_tangent = Fraction(sine / (1.0 + cosine) if cosine > 0 else (1.0 - cosine) / sine)
    scale = 1 + half_tangent**2
    return 2 * half_tangent / scale, (1 - half_tangent**2) / scale


def _residue(value: Fraction, prime: int) -> int:
    """``value`` in Z/pZ; its denominator is a power of two times a sum of two squares."""
    if value.denominator % prime == 0:
        raise ZeroDivisionError(f"{value} has no residue modulo {prime}")
    return value.numerator * pow(value.denominator, -1, prime) % prime


def _growth_vector_any_prime(
    circle_points: list[tuple[Fraction, Fraction]], top_level: int
) -> list[int]:
    """Growth up to full rank or ``top_level``, as the largest dimensions over two primes.

    A dimension modulo p is a lower bound of the true one, reached unless p divides a
    particular minor: the larger of two primes' is exact but with vanishing probability.
    """
    dimension = len(circle_points) + 3
    growths = []
    for prime in _PRIMES:
        try:
            growths.append(_growth_vector(circle_points, prime, top_level))
        except ZeroDivisionError:  # p divides a denominator of the point: use the other
            continue
    if not growths:  # pragma: no cover - needs a point whose denominators both divide
        raise ArithmeticError("the configuration is not representable modulo the primes")
    length = max(len(growth) for growth in growths)
    padded = [growth + [dimension] * (length - len(growth)) for growth in growths]
    combined = [max(dims) for dims in zip(*padded, strict=True)]
    return combined[: combined.index(dimension) + 1] if dimension in combined else combined


def _product_modulo(vector: IntArray, matrix: IntArray, prime: int) -> IntArray:
    """``vector @ matrix`` modulo ``prime``, in chunks short enough not to overflow."""
    result = np.zeros(matrix.shape[1], dtype=np.int64)
    for start in range(0, vector.shape[0], _MAX_TERMS_PER_SUM):
        chunk = slice(start, start + _MAX_TERMS_PER_SUM)
        result = (result + vector[chunk] @ matrix[chunk] % prime) % prime
    return result


def _echelon_rows(matrix: IntArray, prime: int) -> IntArray:
    """Reduced row echelon basis (modulo ``prime``) of the span of the rows of ``matrix``."""
    basis = np.zeros((0, matrix.shape[1]), dtype=np.int64)
    pivot_columns: list[int] = []
    for row in matrix:
        if pivot_columns:
            # basis is reduced, so one product clears every pivot column at once.
            row = (row - _product_modulo(row[pivot_columns], basis, prime)) % prime
        nonzero = np.flatnonzero(row)
        if nonzero.size == 0:
            continue
        column = int(nonzero[0])
        row = row * pow(int(row[column]), -1, prime) % prime
        basis = (basis - np.outer(basis[:, column], row) % prime) % prime
        basis = np.vstack([basis, row])
        pivot_columns.append(column)
    return basis


# --- the fields' coefficients as sums of separable products ---------------------------


@dataclass(frozen=True)
class _SeparableTerm:
    """``sign * prod_axis sin(alpha_axis + quarter_turns * pi / 2)``."""

    sign: int
    quarter_turns: tuple[tuple[int, int], ...]  # (axis, quarter turns), one per axis

    def derivative(self, axis: int) -> _SeparableTerm | None:
        """d/dalpha_axis; None when the term does not depend on that angle."""
        turns = dict(self.quarter_turns)
        if axis not in turns:
            return None
        turns[axis] += 1  # sin(t + q pi/2)' = sin(t + (q + 1) pi/2)
        return _SeparableTerm(self.sign, tuple(sorted(turns.items())))


_Function = tuple[_SeparableTerm, ...]  # a sum of separable terms


@cache
def _hitch_rates(n: int) -> tuple[_Function, ...]:
    """``A_1..A_n`` (l = 1) as sums of separable terms, alpha_k on axis k - 1."""
    sine, cosine = 0, 1
    rates: list[_Function] = [(_SeparableTerm(-1, ((0, sine),)),)] if n >= 1 else []
    for k in range(2, n + 1):
        chain = tuple((axis, cosine) for axis in range(k - 2))  # prod_{j<=k-2} cos(alpha_j)
        rates.append(
            (
                _SeparableTerm(1, (*chain, (k - 2, sine))),
                _SeparableTerm(-1, (*chain, (k - 2, cosine), (k - 1, sine))),
            )
        )
    return tuple(rates)


@cache
def _hitch_rate_jacobian(n: int) -> tuple[tuple[_Function, ...], ...]:
    """``dA_k/dalpha_j`` indexed ``[k][j]`` from 0 (empty where A_k ignores alpha_j)."""
    return tuple(
        tuple(
            tuple(d for d in (term.derivative(axis) for term in rate) if d is not None)
            for axis in range(n)
        )
        for rate in _hitch_rates(n)
    )


# --- jet arithmetic -------------------------------------------------------------------


@dataclass(frozen=True)
class _Monomials:
    """The multi-indices ``a`` with ``|a| <= top_order`` in n variables, graded.

    Sorted by total degree first, so the multi-indices of order ``<= d`` are a prefix of
    length ``count[d]`` for every ``d``: truncating a jet is slicing it.
    """

    exponents: IntArray  # (size, n)
    count: tuple[int, ...]  # count[d] = number of multi-indices with |a| <= d
    raised: IntArray  # (n, count[top - 1]): position of a + e_j
    # shifted[j][m] = (targets a with a_j >= m, positions of a - m e_j), both ascending
    shifted: tuple[tuple[tuple[IntArray, IntArray], ...], ...]


@lru_cache(maxsize=64)
def _multi_indices(n: int, top_order: int) -> IntArray:
    """All ``a`` in N^n with ``|a| <= top_order``, in no particular order."""
    if n == 0:
        return np.zeros((1, 0), dtype=np.int64)
    blocks = []
    for first in range(top_order + 1):
        rest = _multi_indices(n - 1, top_order - first)
        blocks.append(np.hstack([np.full((rest.shape[0], 1), first, dtype=np.int64), rest]))
    return np.vstack(blocks)


@lru_cache(maxsize=8)  # n = 5 to 21 levels holds about 15 MB
def _monomials(n: int, top_order: int) -> _Monomials:
    exponents = _multi_indices(n, top_order)
    # Graded, then lexicographic: an order that does not depend on top_order.
    exponents = exponents[np.lexsort((*exponents.T[::-1], exponents.sum(axis=1)))]
    degrees = exponents.sum(axis=1)
    count = tuple(int(np.searchsorted(degrees, d, side="right")) for d in range(top_order + 1))
    radix = (top_order + 2) ** np.arange(n)  # exact integer keys for look-ups
    keys = exponents @ radix
    sorter = np.argsort(keys)

    def position(wanted: IntArray) -> IntArray:
        return sorter[np.searchsorted(keys, wanted, sorter=sorter)]

    below_top = count[top_order - 1] if top_order > 0 else 0
    raised = np.array([position(keys[:below_top] + radix[j]) for j in range(n)], dtype=np.int64)
    raised = raised.reshape(n, below_top)
    shifted = tuple(
        tuple(
            (targets, position(keys[targets] - m * radix[j]))
            for m in range(top_order + 1)
            for targets in [np.flatnonzero(exponents[:, j] >= m)]
        )
        for j in range(n)
    )
    return _Monomials(exponents, count, raised, shifted)


class _JetAlgebra:
    """Exact jet arithmetic modulo a prime at a fixed configuration.

    A batch of reduced fields of order ``d`` is an int64 array of shape
    ``(batch, n + 3, count[d])``: along the last axis, the partial derivatives ``d^a`` at
    the point, modulo the prime, for the multi-indices ``a`` of :class:`_Monomials`.
    Derivatives rather than Taylor coefficients: a derivative is a shift, and the product
    rule has integer (binomial) coefficients.
    """

    def __init__(
        self, circle_points: list[tuple[Fraction, Fraction]], prime: int, top_order: int
    ) -> None:
        self.n = len(circle_points)
        self.prime = prime
        self.monomials = _monomials(self.n, top_order)
        # d^m/dt^m sin(t + q pi/2) = sin(t + (q + m) pi/2), and sin(t + q pi/2) cycles
        # through (sin, cos, -sin, -cos): row `axis`, column q mod 4.
        self._cycles = [
            [_residue(value, prime) for value in (sine, cosine, -sine, -cosine)]
            for sine, cosine in circle_points
        ]
        self._binomials = np.array(
            [[math.comb(a, b) % prime for b in range(top_order + 1)] for a in range(top_order + 1)],
            dtype=np.int64,
        )

    def size(self, order: int) -> int:
        return self.monomials.count[order]

    # -- calculus --

    def derivative(self, jets: IntArray, axis: int, order: int) -> IntArray:
        """d/dalpha_axis of fields of ``order``, one order lower: a gather."""
        return jets[..., self.monomials.raised[axis, : self.size(order - 1)]]

    def times(self, function: _Function, jets: IntArray, order: int) -> IntArray:
        """Multiply every field of ``jets`` (of ``order``) by a sum of separable terms."""
        total = np.zeros_like(jets)
        for term in function:
            product = jets if term.sign > 0 else -jets
            for axis, turns in term.quarter_turns:
                product = self._times_sine(product, axis, turns, order)
            total += product
        return total % self.prime

    def _times_sine(self, jets: IntArray, axis: int, turns: int, order: int) -> IntArray:
        """Leibniz rule along one axis for ``phi = sin(alpha_axis + turns pi/2)``.

        ``d^a (phi f) = sum_m C(a_j, m) phi^(m) d^(a - m e_j) f``, j = axis.
        """
        size = self.size(order)
        exponent = self.monomials.exponents[:size, axis]
        result = jets * self._cycles[axis][turns % 4]  # m = 0
        for m in range(1, order + 1):
            targets, sources = self.monomials.shifted[axis][m]
            cut = int(np.searchsorted(targets, size))
            if cut == 0:
                break
            targets, sources = targets[:cut], sources[:cut]
            phi = self._cycles[axis][(turns + m) % 4]
            weights = self._binomials[exponent[targets], m] * phi % self.prime
            # Each term < p^2 < 2^52 and at most order + 1 of them: int64 cannot overflow.
            result[..., targets] += weights * jets[..., sources]
        return result % self.prime

    # -- the fields --

    def generators(self, order: int) -> IntArray:
        """``Z1, Z2`` as a batch of two fields of ``order``."""
        fields = np.zeros((2, self.n + 3, self.size(order)), dtype=np.int64)
        fields[0, _RE, 0] = 1  # Z1: e^{i theta}, i.e. cos(theta) d/dx + sin(theta) d/dy ...
        fields[1, _THETA, 0] = 1  # Z2: d/dtheta ...
        if self.n > 0:
            fields[1, _ALPHA0, 0] = 1  # ... + d/dalpha_1
            one = np.zeros((1, 1, self.size(order)), dtype=np.int64)
            one[0, 0, 0] = 1
            for k, rate in enumerate(_hitch_rates(self.n)):
                fields[0, _ALPHA0 + k] = self.times(rate, one, order)[0, 0]  # + A_k d/dalpha_k
        return fields

    def brackets(self, generator: int, fields: IntArray, order: int) -> IntArray:
        """``[Z, B]`` for ``Z = Z1`` (0) or ``Z2`` (1) and every B of ``fields`` (of ``order``).

        Returned one order lower.
        """
        lower = fields[..., : self.size(order - 1)]
        result = np.zeros_like(lower)
        if generator == 1:
            # Z2 = d/dtheta + d/dalpha_1, and d/dtheta (e^{i theta} g) = e^{i theta} i g.
            result[:, _RE] = -lower[:, _IM]
            result[:, _IM] = lower[:, _RE]
            if self.n > 0:
                result += self.derivative(fields, 0, order)
            return result % self.prime
        # Z1 differentiates B: sum_k A_k dB/dalpha_k.
        for k, rate in enumerate(_hitch_rates(self.n)):
            result += self.times(rate, self.derivative(fields, k, order), order - 1)
        # B differentiates Z1: B(e^{i theta}) = i p e^{i theta}, B(A_k) = sum_j h_j dA_k/dalpha_j.
        result[:, _IM] -= lower[:, _THETA]
        jacobian = _hitch_rate_jacobian(self.n)
        for k in range(self.n):
            for j in range(self.n):
                if jacobian[k][j]:
                    h_j = lower[:, _ALPHA0 + j : _ALPHA0 + j + 1]
                    result[:, _ALPHA0 + k] -= self.times(jacobian[k][j], h_j, order - 1)[:, 0]
        return result % self.prime


# --- the flag of spans ----------------------------------------------------------------


def _growth_vector(
    circle_points: list[tuple[Fraction, Fraction]], prime: int, top_level: int
) -> list[int]:
    """``dim D^1, dim D^2, ...`` until full rank or ``top_level``, modulo one prime."""
    algebra = _JetAlgebra(circle_points, prime, top_order=max(top_level - 1, 0))
    dimension = algebra.n + 3
    level_fields = algebra.generators(max(top_level - 1, 0))
    values = np.zeros((0, dimension), dtype=np.int64)  # echelon basis of D^k at the point
    growth: list[int] = []
    for level in range(1, top_level + 1):
        if level > 1:
            order = top_level - level + 1  # of the fields of the previous level
            brackets = np.concatenate([algebra.brackets(i, level_fields, order) for i in (0, 1)])
            # Bracketing a basis of the level is enough: the bracket is bilinear.
            basis = _echelon_rows(brackets.reshape(brackets.shape[0], -1), prime)
            level_fields = basis.reshape(basis.shape[0], dimension, -1)
        values = _echelon_rows(np.vstack([values, level_fields[:, :, 0]]), prime)
        growth.append(values.shape[0])
        if growth[-1] == dimension:
            break
    return growth
