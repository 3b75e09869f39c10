import math
import warnings

import pytest

from dynamics import ConvoyParams


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
        ("M", "heavy"),
    ],
)
def test_invalid_values_name_the_parameter(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=field):
        ConvoyParams(**{field: value})  # type: ignore[arg-type]


@pytest.mark.parametrize("n", [-1, 1.5, "2", True])
def test_invalid_trailer_count(n: object) -> None:
    with pytest.raises(ValueError, match="n_trailers"):
        ConvoyParams(n_trailers=n)  # type: ignore[arg-type]


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
    with pytest.raises(ValueError, match="unknown ConvoyParams field"):
        params.replace(mass=3.0)
    with pytest.raises(ValueError, match="l must be > 0"):
        params.replace(l=0.0)


def test_params_are_frozen() -> None:
    params = ConvoyParams()
    with pytest.raises(AttributeError):
        params.M = 2.0  # type: ignore[misc]
