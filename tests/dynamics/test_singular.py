from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from dynamics import is_jackknifed, singular_margin


def test_margin_ignores_the_last_trailer() -> None:
    assert singular_margin([np.pi / 2]) == 1.0
    assert singular_margin([0.0, np.pi / 2]) == 1.0
    assert singular_margin(np.zeros(0)) == 1.0
    assert singular_margin([np.pi / 2, 0.0]) == pytest.approx(0.0, abs=1e-15)
    assert singular_margin([0.5, 1.0, 2.0]) == pytest.approx(abs(np.cos(1.0)))


def test_margin_is_batched() -> None:
    margins = singular_margin(np.array([[0.0, 0.3, 0.0], [1.2, 0.0, 0.0]]))
    np.testing.assert_allclose(margins, [np.cos(0.3), np.cos(1.2)])


@given(arrays(np.float64, st.integers(0, 6), elements=st.floats(-10, 10)))
def test_margin_is_in_unit_interval_and_even(alpha: np.ndarray) -> None:
    margin = singular_margin(alpha)
    assert 0.0 <= margin <= 1.0
    assert singular_margin(-alpha) == margin


def test_jackknife_uses_wrapped_angles_and_includes_the_last_trailer() -> None:
    assert not is_jackknifed([0.1, -1.5])
    assert is_jackknifed([0.1, -1.6])
    assert is_jackknifed([2 * np.pi + 1.6, 0.0])
    assert not is_jackknifed([2 * np.pi + 0.2, 0.0])
    assert not is_jackknifed(np.zeros(0))
    assert is_jackknifed([0.5], fold_angle=0.4)


def test_non_finite_angles_are_rejected() -> None:
    with pytest.raises(ValueError, match="non-finite"):
        singular_margin([0.0, np.inf])
