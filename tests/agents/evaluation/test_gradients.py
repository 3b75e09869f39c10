"""python -m agents.gradients: exact policy gradients through the twin, and their figures."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from agents.commands.gradients import main
from agents.evaluation.gradients import (
    EXPLODED,
    OUTPUTS,
    returns_and_gradients,
    start_gains,
    statistics,
)

SEED = 50000  # validation starts


@pytest.mark.parametrize("policy", ["lqr", "zero"])
def test_the_gradient_is_the_returns_derivative(policy: str) -> None:
    n, horizon = 2, 12
    gains = start_gains(n, policy, 3, SEED)
    found = returns_and_gradients(n, gains, [horizon], SEED)
    returns, gradient = found[horizon]
    assert gradient is not None and gradient.shape == (3, n + 3)
    assert np.all(np.isfinite(gradient)) and np.abs(gradient).max() > 0.0
    # Central differences of the return in each gain of start 0 (its own K only).
    step = 1e-5
    for column in range(n + 3):
        shifted = []
        for sign in (1.0, -1.0):
            moved = gains.copy()
            moved[0, column] += sign * step
            value, none = returns_and_gradients(n, moved, [horizon], SEED, differentiate=False)[
                horizon
            ]
            assert none is None
            shifted.append(value)
            # The other starts do not see start 0's gains.
            np.testing.assert_array_equal(value[1:], returns[1:])
        difference = (shifted[0][0] - shifted[1][0]) / (2 * step)
        # Measured: agreement to about 1e-9 of the gradient's size.
        assert difference == pytest.approx(gradient[0, column], rel=1e-5, abs=1e-9)


def test_statistics_of_known_gradients() -> None:
    gradients = np.array([[3.0, 4.0], [3.0, 4.0], [np.inf, 0.0], [2 * EXPLODED, 0.0]])
    cell = statistics(gradients)
    assert cell["exploded"] == 0.5
    assert cell["median_norm"] == pytest.approx(5.0)  # of the finite norms 5, 5, 2e6
    assert cell["mean_gradient_norm"] == pytest.approx(5.0)
    assert cell["spread"] == 0.0


def test_the_command_writes_its_files_and_refuses_to_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "gradients"
    argv = ["--n", "1", "--starts", "4", "--max-horizon", "32", "--seed", str(SEED)]
    assert main([*argv, "--out", str(out)]) == 0
    assert sorted(path.name for path in out.iterdir()) == sorted(OUTPUTS)
    document = json.loads((out / "gradients.json").read_text())
    assert document["horizons"] == [1, 2, 4, 8, 16, 32]
    zero = document["by_policy"]["zero"]["1"]
    # Without feedback the reversing convoy is unstable: the gradient grows with H.
    norms = [zero[str(h)]["median_norm"] for h in (1, 4, 16, 32)]
    assert norms == sorted(norms) and norms[-1] > 100 * norms[0]
    assert "| 1 |" in (out / "gradients.md").read_text()
    capsys.readouterr()
    with pytest.raises(SystemExit) as refused:
        main([*argv, "--out", str(out)])
    assert refused.value.code == 2
    assert "--overwrite" in capsys.readouterr().err
    # --redraw writes the same table from the JSON; a damaged JSON is refused whole.
    table = (out / "gradients.md").read_text()
    (out / "gradients.md").unlink()
    assert main(["--out", str(out), "--redraw"]) == 0
    assert (out / "gradients.md").read_text() == table
    document["by_policy"]["zero"]["1"]["4"] = "big"
    (out / "gradients.json").write_text(json.dumps(document))
    with pytest.raises(SystemExit) as refused:
        main(["--out", str(out), "--redraw"])
    assert refused.value.code == 2 and "not a gradients document" in capsys.readouterr().err
    assert (out / "gradients.md").read_text() == table


def test_an_unknown_policy_is_refused() -> None:
    with pytest.raises(ValueError, match="policy must be one of"):
        start_gains(1, "ppo", 2, SEED)
