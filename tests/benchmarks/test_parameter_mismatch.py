"""``benchmarks.parameter_mismatch``: the gains and the safe rates it reports."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks import parameter_mismatch


@pytest.fixture(scope="module")
def rows() -> dict[str, dict]:
    return {row["change"]: row for row in parameter_mismatch.cases(2, episodes=4)}


def test_the_trailers_mass_and_inertia_leave_the_gains_and_the_episodes_as_they_are(
    rows: dict[str, dict],
) -> None:
    for change in ("m x 0.8", "m x 1.2", "J x 0.8", "J x 1.2"):
        assert rows[change]["gain_change"] == 0.0
        assert rows[change]["nominal_gains"] == rows["none"]["nominal_gains"]


def test_the_authority_changes_the_gain_and_the_nominal_lqr_loses_it(
    rows: dict[str, dict],
) -> None:
    assert rows["mu x 0.8"]["gain_change"] == pytest.approx(0.085, abs=0.005)
    assert rows["a x 1.2"]["gain_change"] == pytest.approx(0.078, abs=0.005)
    assert rows["none"]["nominal_gains"] == rows["none"]["redesigned"]
    assert np.isnan(rows["randomize=mismatch20"]["gain_change"])
    assert set(rows) >= {"randomize=mismatch10", "randomize=mismatch20"}
