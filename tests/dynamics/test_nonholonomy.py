"""Degree of nonholonomy (physics.md section 10), checked against independent computations.

The oracle here shares nothing with ``dynamics.nonholonomy`` but the definition of the
fields: it works in the full coordinates ``(x, y, theta, alpha_1..alpha_n)`` (no SE(2)
reduction, no jets), brackets the fields symbolically with sympy as polynomials in the
sines and cosines, uses the Lyndon (Hall) basis of the free Lie algebra instead of
right-normed brackets and reduced spans, and takes exact ranks over the rationals at
points with rational sines and cosines (Pythagorean triples, or 0 and 1 at pi/2).

Values found (the same by both computations; generic angles elsewhere, alpha_n never
matters; ``S`` is the set of k with cos(alpha_k) = 0):

=====  =========  ======  =====================================================
n      S          degree  growth vector
=====  =========  ======  =====================================================
0-5    (none)     n + 2   (2, 3, ..., n + 3)  (oracle: n <= 4)
2      {1}        5       (2, 3, 4, 4, 5)
3      {2}        6       (2, 3, 4, 5, 5, 6)
3      {1}        7       (2, 3, 4, 4, 5, 5, 6)
3      {1, 2}     8       (2, 3, 4, 4, 5, 5, 5, 6)
4      {3}        7       (2, 3, 4, 5, 6, 6, 7)
4      {2}        8       (2, 3, 4, 5, 5, 6, 6, 7)
4      {1}        9       (2, 3, 4, 4, 5, 5, 6, 6, 7)
4      {2, 3}     9       (2, 3, 4, 5, 5, 6, 6, 6, 7)
4      {1, 2}     11      (2, 3, 4, 4, 5, 5, 5, 6, 6, 6, 7)
4      {1, 3}     11      (2, 3, 4, 4, 5, 5, 6, 6, 6, 6, 7)
4      {1, 2, 3}  13      (2, 3, 4, 4, 5, 5, 5, 6, 6, 6, 6, 6, 7)
5      {k}        12 - k  (module only; k = 1..4)
5      {1..4}     21      (module only)
=====  =========  ======  =====================================================

A single singular angle alpha_k gives degree 2n + 2 - k; every consecutive pair
perpendicular gives the Fibonacci number F_{n+3} (2, 3, 5, 8, 13, 21 for n = 0..5), the
bound of Luca-Risler and Jean (1996), reached exactly there. Run times of
``nonholonomy_degree`` on one core: under 0.03 s for n <= 3, under 0.2 s for every n = 4
configuration (13 levels), under 1 s for n = 5 with one singular angle and 8 to 12 s with
every pair perpendicular (21 levels, marked slow). The symbolic oracle takes under 0.5 s
except for n = 4 with two singular angles (about 2.5 s each) and with three (about 20 s,
marked slow).
"""

from __future__ import annotations

import itertools
import math
from fractions import Fraction
from functools import cache

import numpy as np
import pytest
import sympy
from sympy.polys.rings import PolyElement

from dynamics.nonholonomy import NonholonomyDegree, fibonacci, nonholonomy_degree

HALF_PI = math.pi / 2
# F_1..F_9, written out so that the oracle does not lean on the module's helper.
FIBONACCI = (1, 1, 2, 3, 5, 8, 13, 21, 34)


def fibonacci_bound(n: int) -> int:
    """F_{n+3}: the largest degree of nonholonomy of the n-trailer system."""
    return FIBONACCI[n + 2]


# Rational points (sin, cos) of the unit circle, away from the axes, for generic angles.
PYTHAGOREAN = [
    (Fraction(3, 5), Fraction(4, 5)),
    (Fraction(5, 13), Fraction(-12, 13)),
    (Fraction(-8, 17), Fraction(15, 17)),
    (Fraction(-7, 25), Fraction(-24, 25)),
    (Fraction(20, 29), Fraction(21, 29)),
]
PERPENDICULAR = (Fraction(1), Fraction(0))  # alpha = pi/2
PERPENDICULAR_BACKWARDS = (Fraction(-1), Fraction(0))  # alpha = -pi/2

EXPECTED_SINGULAR = {
    (2, (1,)): (2, 3, 4, 4, 5),
    (3, (2,)): (2, 3, 4, 5, 5, 6),
    (3, (1,)): (2, 3, 4, 4, 5, 5, 6),
    (3, (1, 2)): (2, 3, 4, 4, 5, 5, 5, 6),
    (4, (3,)): (2, 3, 4, 5, 6, 6, 7),
    (4, (2,)): (2, 3, 4, 5, 5, 6, 6, 7),
    (4, (1,)): (2, 3, 4, 4, 5, 5, 6, 6, 7),
    (4, (2, 3)): (2, 3, 4, 5, 5, 6, 6, 6, 7),
    (4, (1, 2)): (2, 3, 4, 4, 5, 5, 5, 6, 6, 6, 7),
    (4, (1, 3)): (2, 3, 4, 4, 5, 5, 6, 6, 6, 6, 7),
    (4, (1, 2, 3)): (2, 3, 4, 4, 5, 5, 5, 6, 6, 6, 6, 6, 7),
}
SLOW_ORACLE = {(4, (1, 2, 3))}


def regular_growth(n: int) -> tuple[int, ...]:
    return tuple(range(2, n + 4))


def angle(point: tuple[Fraction, Fraction]) -> float:
    sine, cosine = point
    return math.atan2(sine, cosine)


def singular_points(n: int, perpendicular: tuple[int, ...]) -> list[tuple[Fraction, Fraction]]:
    """Exact (sin, cos) of each alpha_k: pi/2 (alternating sign) for k in ``perpendicular``."""
    points = list(PYTHAGOREAN[:n])
    for index, k in enumerate(perpendicular):
        points[k - 1] = PERPENDICULAR if index % 2 == 0 else PERPENDICULAR_BACKWARDS
    return points


# --- the independent oracle -------------------------------------------------------------


def lyndon_words(max_length: int) -> list[tuple[int, ...]]:
    """Lyndon words over the letters 1 < 2 of length <= max_length (Duval's algorithm)."""
    words = []
    word = [-1]
    while word:
        word[-1] += 1
        words.append(tuple(letter + 1 for letter in word))
        period = len(word)
        while len(word) < max_length:
            word.append(word[len(word) - period])
        while word and word[-1] == 1:
            word.pop()
    return sorted(words, key=len)


def is_lyndon(word: tuple[int, ...]) -> bool:
    return all(word < word[i:] for i in range(1, len(word)))


def standard_factorization(word: tuple[int, ...]) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """word = u v with v its longest proper Lyndon suffix: [word] = [[u], [v]]."""
    for split in range(1, len(word)):
        if is_lyndon(word[split:]):
            return word[:split], word[split:]
    raise ValueError(f"{word} has length 1")


def oracle_growth(
    n: int, points: list[tuple[Fraction, Fraction]], theta: tuple[Fraction, Fraction]
) -> tuple[int, ...]:
    """Growth vector by symbolic Lyndon brackets and exact ranks, up to F_{n+3} levels.

    ``points`` are the exact (sin, cos) of alpha_1..alpha_n and ``theta`` that of theta.
    """
    names = ["cos_theta", "sin_theta"] + [f"{f}{k}" for k in range(1, n + 1) for f in "cs"]
    ring, *symbols = sympy.ring(names, sympy.QQ)
    # (cos, sin) of theta, alpha_1, ..., alpha_n: d/dangle acts as c d/ds - s d/dc.
    pairs = [(symbols[2 * i], symbols[2 * i + 1]) for i in range(n + 1)]
    cos_a = [pairs[k][0] for k in range(1, n + 1)]
    sin_a = [pairs[k][1] for k in range(1, n + 1)]
    circle = [c**2 + s**2 - 1 for c, s in pairs]

    def d(f: PolyElement, index: int) -> PolyElement:
        c, s = pairs[index]
        return c * f.diff(s) - s * f.diff(c)

    rates = [-sin_a[0]] if n else []
    for k in range(2, n + 1):
        chain = math.prod(cos_a[: k - 2], start=ring.one)
        rates.append(chain * (sin_a[k - 2] - cos_a[k - 2] * sin_a[k - 1]))
    z1 = [pairs[0][0], pairs[0][1], ring.zero, *rates]
    z2 = [ring.zero, ring.zero, ring.one] + [ring.one if k == 0 else ring.zero for k in range(n)]
    dimension = n + 3

    def bracket(first: list[PolyElement], second: list[PolyElement]) -> list[PolyElement]:
        # [X, Y]^i = X(Y^i) - Y(X^i); only theta (index 0) and the alphas are coordinates
        # the coefficients depend on; x and y (components 0 and 1) never appear.
        return [
            sum(
                (
                    first[2 + j] * d(second[i], j) - second[2 + j] * d(first[i], j)
                    for j in range(n + 1)
                ),
                ring.zero,
            ).rem(circle)
            for i in range(dimension)
        ]

    @cache
    def field(word: tuple[int, ...]) -> list[PolyElement]:
        if len(word) == 1:
            return z1 if word == (1,) else z2
        left, right = standard_factorization(word)
        return bracket(field(left), field(right))

    values = []
    for sine, cosine in [theta, *points]:
        values += [sympy.QQ(cosine.numerator, cosine.denominator)]
        values += [sympy.QQ(sine.numerator, sine.denominator)]

    def at_point(f: PolyElement) -> sympy.Expr:
        # Term by term: much faster than PolyElement.__call__, which substitutes one
        # variable at a time.
        total = sympy.QQ.zero
        for monomial, coefficient in f.terms():
            for value, exponent in zip(values, monomial, strict=True):
                if exponent:
                    coefficient *= value**exponent
            total += coefficient
        return sympy.QQ.to_sympy(total)

    words = lyndon_words(fibonacci_bound(n))
    rows: list[list[sympy.Expr]] = []
    growth: list[int] = []
    for level in range(1, fibonacci_bound(n) + 1):
        rows += [
            [at_point(component) for component in field(word)]
            for word in words
            if len(word) == level
        ]
        growth.append(sympy.Matrix(rows).rank())
        if growth[-1] == dimension:
            break
    return tuple(growth)


# --- tests ----------------------------------------------------------------------------


def test_fibonacci_numbers() -> None:
    assert tuple(fibonacci(k) for k in range(1, 10)) == FIBONACCI


def test_lyndon_words_count_the_free_lie_algebra() -> None:
    # Witt's formula for two generators: 2, 1, 2, 3, 6, 9, 18, 30 words of length 1..8.
    lengths = [len(word) for word in lyndon_words(8)]
    assert [lengths.count(k) for k in range(1, 9)] == [2, 1, 2, 3, 6, 9, 18, 30]


def test_sleigh_has_degree_two() -> None:
    expected = NonholonomyDegree(degree=2, growth_vector=(2, 3))
    assert nonholonomy_degree(0, []) == expected
    assert nonholonomy_degree(0, [1.0, -2.0, 0.7]) == expected  # (x, y, theta)


@pytest.mark.parametrize("n", range(6))
def test_regular_points_have_degree_n_plus_2(n: int, rng: np.random.Generator) -> None:
    for _ in range(3):
        alphas = rng.uniform(-np.pi, np.pi, n)
        # Away from the singular set: |cos(alpha_k)| >= 0.2 for k <= n - 1.
        alphas[:-1] = np.where(np.abs(np.cos(alphas[:-1])) < 0.2, 0.4, alphas[:-1])
        result = nonholonomy_degree(n, alphas)
        assert result.degree == n + 2
        assert result.growth_vector == regular_growth(n)


@pytest.mark.parametrize("n", range(5))
def test_regular_points_match_the_oracle(n: int) -> None:
    points = PYTHAGOREAN[:n]
    expected = regular_growth(n)
    assert oracle_growth(n, points, PYTHAGOREAN[-1]) == expected
    assert nonholonomy_degree(n, [angle(point) for point in points]).growth_vector == expected


@pytest.mark.parametrize(
    ("n", "perpendicular"),
    [
        pytest.param(*case, marks=pytest.mark.slow) if case in SLOW_ORACLE else case
        for case in EXPECTED_SINGULAR
    ],
)
def test_singular_points_match_the_oracle(n: int, perpendicular: tuple[int, ...]) -> None:
    points = singular_points(n, perpendicular)
    expected = EXPECTED_SINGULAR[n, perpendicular]
    theta = PYTHAGOREAN[-1]
    assert oracle_growth(n, points, theta) == expected
    config = [0.5, -1.5, angle(theta)] + [angle(point) for point in points]
    result = nonholonomy_degree(n, config)
    assert result == NonholonomyDegree(degree=len(expected), growth_vector=expected)


@pytest.mark.parametrize(("n", "perpendicular"), list(EXPECTED_SINGULAR))
def test_singular_points_recorded_values(n: int, perpendicular: tuple[int, ...]) -> None:
    """The module alone, at other generic angles than the oracle's."""
    alphas = np.array([0.3, -1.1, 2.0, 0.9, -0.4][:n])
    alphas[[k - 1 for k in perpendicular]] = -HALF_PI
    expected = EXPECTED_SINGULAR[n, perpendicular]
    assert nonholonomy_degree(n, alphas).growth_vector == expected


@pytest.mark.parametrize("n", range(2, 5))
def test_singular_degrees_respect_the_fibonacci_bound(n: int) -> None:
    for size in range(1, n):
        for perpendicular in itertools.combinations(range(1, n), size):
            alphas = np.full(n, 0.7)
            alphas[[k - 1 for k in perpendicular]] = HALF_PI
            result = nonholonomy_degree(n, alphas)
            assert n + 2 < result.degree <= fibonacci_bound(n)
            # A singular angle alpha_k alone costs n - k extra levels.
            if size == 1:
                assert result.degree == 2 * n + 2 - perpendicular[0]


@pytest.mark.parametrize("n", range(1, 5))
def test_all_consecutive_perpendicular_reaches_the_fibonacci_bound(n: int) -> None:
    alphas = [HALF_PI] * (n - 1) + [0.3]
    result = nonholonomy_degree(n, alphas)
    assert result.degree == fibonacci_bound(n)
    assert result.growth_vector[-1] == n + 3


FIVE_TRAILERS_ONE_SINGULAR = {
    1: (2, 3, 4, 4, 5, 5, 6, 6, 7, 7, 8),
    2: (2, 3, 4, 5, 5, 6, 6, 7, 7, 8),
    3: (2, 3, 4, 5, 6, 6, 7, 7, 8),
    4: (2, 3, 4, 5, 6, 7, 7, 8),
}


@pytest.mark.parametrize("k", range(1, 5))
def test_five_trailers_one_singular_angle(k: int) -> None:
    alphas = np.array([0.3, -0.5, 0.7, 0.2, 0.4])
    alphas[k - 1] = HALF_PI
    result = nonholonomy_degree(5, alphas)
    assert result.degree == 2 * 5 + 2 - k
    assert result.growth_vector == FIVE_TRAILERS_ONE_SINGULAR[k]


@pytest.mark.slow
def test_five_trailers_all_perpendicular_reach_f8() -> None:
    result = nonholonomy_degree(5, [HALF_PI, -HALF_PI, HALF_PI, -HALF_PI, 1.0])
    assert result.degree == fibonacci_bound(5) == 21
    assert result.growth_vector[:8] == (2, 3, 4, 4, 5, 5, 5, 6)


@pytest.mark.parametrize("n", range(1, 6))
def test_last_trailer_perpendicular_alone_is_regular(n: int) -> None:
    alphas = [0.4, -0.6, 0.2, 1.0][: n - 1]
    for last in (HALF_PI, -HALF_PI):
        result = nonholonomy_degree(n, [*alphas, last])
        assert result.growth_vector == regular_growth(n)


@pytest.mark.parametrize(
    "alphas",
    [[0.4, -1.0, 2.5], [HALF_PI, 0.3, -0.8], [0.2, HALF_PI, HALF_PI], [HALF_PI, HALF_PI, 0.0]],
)
def test_symmetries(alphas: list[float]) -> None:
    reference = nonholonomy_degree(3, alphas)
    reflected = nonholonomy_degree(3, [-a for a in alphas])
    turned = nonholonomy_degree(
        3, [a + 2 * np.pi * k for a, k in zip(alphas, (1, -2, 3), strict=True)]
    )
    assert reference == reflected == turned


def test_position_and_heading_do_not_matter() -> None:
    alphas = [HALF_PI, 0.3, -0.8]
    reference = nonholonomy_degree(3, alphas)
    for x, y, theta in [(0.0, 0.0, 0.0), (3.0, -2.0, 1.2), (-1e3, 5.0, -3.0)]:
        assert nonholonomy_degree(3, [x, y, theta, *alphas]) == reference


def test_near_singular_points() -> None:
    # Exact arithmetic: any genuine distance from the singular set is regular ...
    assert nonholonomy_degree(2, [HALF_PI + 1e-6, 0.4]).degree == 4
    assert nonholonomy_degree(2, [HALF_PI + 1e-12, 0.4], rtol=1e-14).degree == 4
    # ... and rtol says how close to pi/2 is read as pi/2.
    assert nonholonomy_degree(2, [HALF_PI + 1e-12, 0.4]).degree == 5
    assert nonholonomy_degree(2, [HALF_PI + 1e-6, 0.4], rtol=1e-5).degree == 5


def test_straight_and_folded_convoys() -> None:
    # sin = 0 is exact too: the straight convoy and a fully folded one are regular.
    assert nonholonomy_degree(3, [0.0, 0.0, 0.0]).degree == 5
    assert nonholonomy_degree(3, [np.pi, -np.pi, np.pi]).degree == 5


def test_options_accept_numpy_scalars() -> None:
    result = nonholonomy_degree(
        np.int64(2),  # type: ignore[arg-type]
        [HALF_PI, 0.4],
        max_level=np.int32(9),  # type: ignore[arg-type]
        rtol=np.float32(1e-6),  # type: ignore[arg-type]
    )
    assert result.degree == 5


def test_max_level() -> None:
    alphas = [HALF_PI, HALF_PI, 0.2]
    assert nonholonomy_degree(3, alphas, max_level=8).degree == 8
    assert nonholonomy_degree(3, alphas, max_level=30).degree == 8
    with pytest.raises(RuntimeError, match="max_level=7"):
        nonholonomy_degree(3, alphas, max_level=7)
    with pytest.raises(RuntimeError, match="max_level=2"):
        nonholonomy_degree(2, [0.1, 0.2], max_level=2)


@pytest.mark.parametrize(
    ("n", "config", "match"),
    [
        (-1, [], "n must be"),
        (1.5, [0.1], "n must be"),
        (True, [0.1], "n must be"),
        ("2", [0.1, 0.2], "n must be"),
        (2, [0.1], "shape"),
        (2, [0.1, 0.2, 0.3], "shape"),
        (2, [[0.1, 0.2]], "shape"),
        (2, 0.1, "shape"),
        (2, [0.1, np.nan], "non-finite"),
        (2, [np.inf, 0.1], "non-finite"),
        (2, ["a", "b"], "real numbers"),
    ],
)
def test_invalid_configuration(n: object, config: object, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        nonholonomy_degree(n, config)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"max_level": 0}, "max_level"),
        ({"max_level": 2.5}, "max_level"),
        ({"max_level": 5000}, "max_level"),
        ({"rtol": 0.0}, "rtol"),
        ({"rtol": -1e-9}, "rtol"),
        ({"rtol": float("nan")}, "rtol"),
        ({"rtol": 1.0}, "rtol"),
    ],
)
def test_invalid_options(options: dict[str, float], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        nonholonomy_degree(2, [0.1, 0.2], **options)  # type: ignore[arg-type]
