import math
import re
import warnings

import numpy as np
import pytest

from dynamics import ConvoyParams
from dynamics.params import MAX_TRAILERS


def test_defaults_are_valid_and_physical() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        params = ConvoyParams()
    assert params.n_trailers == 2
    assert pytest.approx(params.J0 + params.M * params.a**2) == params.I0
    assert params.n_state == 4
    assert params.m * params.l**2 > params.J


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("M", 0.0),
        ("m", -1.0),
        ("J0", 0.0),
        ("l", -0.5),
        ("J", -0.1),
        ("mu", -0.01),
        ("s_max", 0.0),
        ("a", math.nan),
        ("b", math.inf),
        # Magnitudes that would overflow later are refused up front, naming the range.
        ("M", 10**400),
        ("M", 1e300),
        ("mu", 1e300),
        ("b", 1e300),
        ("a", 1e300),
        ("l", 1e300),
        ("l", 1e-8),
        ("l", 1e-300),
        ("J0", 1e-300),
        ("s_max", 1e7),
    ],
)
def test_invalid_values_name_the_parameter(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=f"^{field} must be"):
        ConvoyParams(**{field: value})  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("field", "value", "accepted_range"),
    [
        ("M", 1e300, "[1e-06, 1e+06]"),
        ("l", 1e-8, "[1e-06, 1e+06]"),
        ("a", -1e7, "[-1e+06, 1e+06]"),
        ("mu", 10**400, "[0, 1e+06]"),
        ("J", -1.0, "[0, 1e+18]"),
    ],
)
def test_out_of_range_message_gives_the_range(
    field: str, value: object, accepted_range: str
) -> None:
    with pytest.raises(ValueError, match=re.escape(accepted_range)):
        ConvoyParams(**{field: value})  # type: ignore[arg-type]


@pytest.mark.parametrize("value", ["heavy", "0.1", True, np.bool_(True), 1 + 0j, None, [1.0]])
@pytest.mark.parametrize("field", ["M", "l", "mu", "b"])
def test_values_that_are_not_real_numbers_are_a_type_error(field: str, value: object) -> None:
    with pytest.raises(TypeError, match=f"^{field} must be a real number"):
        ConvoyParams(**{field: value})  # type: ignore[arg-type]


def test_range_edges_are_accepted_and_numpy_scalars_become_floats() -> None:
    small = ConvoyParams(
        M=1e-6, m=5e-4, mu=5e-4, l=1e-6, a=-5e-4, b=5e-4, s_max=5e-4, J=0.0, J0=1e-18
    )
    assert (small.M, small.l, small.a, small.J0) == (1e-6, 1e-6, -5e-4, 1e-18)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # J = m l^2 warns
        large = ConvoyParams(M=1e6, m=1e6, mu=1e6, l=1e6, a=1e6, b=-1e6, s_max=1e6, J=1e18, J0=1e18)
    assert (large.M, large.l, large.b, large.J) == (1e6, 1e6, -1e6, 1e18)
    params = ConvoyParams(M=np.float32(2.0), l=np.int64(3))
    assert type(params.M) is float and type(params.l) is float
    assert (params.M, params.l) == (2.0, 3.0)


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"M": 1e-3, "m": 2.0}, r"m / M = 2e\+03 exceeds 1000 \(m = 2, M = 0.001\)"),
        ({"M": 2e3, "m": 1.0}, "M / m"),
        ({"mu": 2e3}, "mu / M"),
        ({"a": -2e3}, r"\|a\| / l"),
        ({"b": 2e3}, r"\|b\| / l"),
        ({"l": 1e-4, "a": 0.0, "b": 0.0, "J": 0.0}, r"s_max / l = 5e\+03"),
        ({"J0": 1e-7}, r"J0 / \(M l\*\*2\) = 1e-07 is outside \[1e-06, 1e\+06\]"),
        ({"J0": 2e6}, "J0 / "),
        ({"J": 101.0}, r"J = 101 exceeds 100 m l\*\*2 = 100 \(m = 1, l = 1\)"),
    ],
)
def test_ratios_are_bounded(changes: dict, match: str) -> None:
    """Each field in range, but one part of the convoy dwarfing another: refused."""
    with pytest.raises(ValueError, match=match):
        ConvoyParams(**changes)


@pytest.mark.parametrize("n", [-1, 1.5, math.inf, math.nan, MAX_TRAILERS + 1, 10**9, 10**400])
def test_invalid_trailer_count(n: object) -> None:
    with pytest.raises(
        ValueError, match=f"n_trailers must be an integer in \\[0, {MAX_TRAILERS}\\]"
    ):
        ConvoyParams(n_trailers=n)  # type: ignore[arg-type]


@pytest.mark.parametrize("n", ["2", True, np.bool_(False), None, 2 + 0j])
def test_trailer_count_of_the_wrong_type(n: object) -> None:
    with pytest.raises(TypeError, match="n_trailers must be an integer"):
        ConvoyParams(n_trailers=n)  # type: ignore[arg-type]


def test_largest_trailer_count_is_accepted() -> None:
    assert ConvoyParams(n_trailers=MAX_TRAILERS).n_state == MAX_TRAILERS + 2


def test_integral_float_trailer_count_is_accepted() -> None:
    assert ConvoyParams(n_trailers=3.0).n_trailers == 3  # type: ignore[arg-type]


def test_unphysical_trailer_inertia_warns_but_is_allowed() -> None:
    with pytest.warns(UserWarning, match="m\\*l\\*\\*2"):
        params = ConvoyParams(m=1.0, l=1.0, J=1.5)
    assert params.J == 1.5


def test_negative_a_and_b_are_allowed() -> None:
    params = ConvoyParams(a=-0.3, b=-0.2, mu=0.0)
    assert (params.a, params.b, params.mu) == (-0.3, -0.2, 0.0)


def test_replace_validates_and_rejects_unknown_fields() -> None:
    params = ConvoyParams()
    assert params.replace(n_trailers=5).n_trailers == 5
    with pytest.raises(TypeError, match="unknown ConvoyParams field"):
        params.replace(mass=3.0)
    with pytest.raises(ValueError, match="l must be in"):
        params.replace(l=0.0)


def test_params_are_frozen() -> None:
    params = ConvoyParams()
    with pytest.raises(AttributeError):
        params.M = 2.0  # type: ignore[misc]
