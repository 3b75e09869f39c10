"""agents.gains: a policy's gains at the straight convoy, n by n."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from agents.commands.gains import main
from agents.envs import env_settings
from agents.evaluation.gains import STEP, markdown, policy_gains, straight_observations
from trailer_env.controllers import LQRController

REVERSE = "trailer_env/Reverse-v1"


def test_the_observations_set_one_hitch_angle_at_a_time() -> None:
    obs = straight_observations(REVERSE, 2, 1000)
    assert obs.shape == (5, obs.shape[1]) and obs.dtype == np.float32
    sines, cosines = obs[:, 2:4], obs[:, 4:6]
    np.testing.assert_array_equal(sines[0], [0.0, 0.0])
    np.testing.assert_array_equal(cosines[0], [1.0, 1.0])
    expected = np.float32(np.sin(STEP))
    np.testing.assert_array_equal(
        sines[1:], [[expected, 0], [-expected, 0], [0, expected], [0, -expected]]
    )
    np.testing.assert_array_equal(obs[:, 6:], np.broadcast_to(obs[0, 6:], obs[:, 6:].shape))
    np.testing.assert_array_equal(obs[:, :2], np.broadcast_to(obs[0, :2], (5, 2)))


@pytest.mark.parametrize("n", [1, 3, 5])
def test_the_lqr_gains_are_its_riccati_design(n: int) -> None:
    # The regulator commands a map of -K x, linear near the straight convoy: the measured
    # gains are its design's angle gains times one factor, the same for every trailer.
    gains = np.array(policy_gains("lqr", REVERSE, n, 1000))
    controller = LQRController(env_settings({"n_trailers": n}))
    speed = straight_observations(REVERSE, n, 1000)[:1, 0].astype(np.float64)
    design = -controller.gains(speed)[0, 1 : 1 + n]
    ratio = gains / design
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-3)
    assert ratio[0] > 0.0 and np.all(np.abs(gains) > 1.0)


def test_the_command_writes_every_n_and_says_why_a_cell_is_empty(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "gains"
    args = ["--n", "2,4", "--policy", "lqr", "dagger_reverse_v1_general", "--out", str(out)]
    assert main([*args, "--specialist", "dagger_reverse_v1_n{n}"]) == 0
    document = json.loads((out / "gains.json").read_text())
    lines = document["lines"]
    assert len(lines["lqr"]["2"]) == 2 and len(lines["lqr"]["4"]) == 4
    assert len(lines["dagger_reverse_v1_general"]["2"]) == 2
    assert lines["dagger_reverse_v1_general"]["4"].startswith("refused: ")  # padded to 3
    assert len(lines["specialist (own n)"]["4"]) == 4
    # The specialists stabilise: gains of alternating sign along the convoy at n = 4.
    signs = np.sign(lines["specialist (own n)"]["4"])
    assert np.all(signs[1:] == -signs[:-1])
    assert (out / "gains.png").stat().st_size > 10_000
    table = (out / "gains.md").read_text()
    assert "| policy | g_1 | g_2 | g_3 | g_4 |" in table
    assert "| dagger_reverse_v1_general | - | - | - | - |" in table
    capsys.readouterr()
    with pytest.raises(SystemExit) as refused:
        main(args)  # the files exist: refused without --overwrite
    assert refused.value.code == 2 and "pass --overwrite" in capsys.readouterr().err


def test_bad_specialists_exit_before_anything_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "gains"
    for spec, message in (
        ("dagger_reverse_v1_n3", "the spec must hold {n}"),
        ("1-3=a_{n},b_{m}", "{m}"),
    ):
        with pytest.raises(SystemExit) as refused:
            main(["--specialist", spec, "--out", str(out)])
        assert refused.value.code == 2 and message in capsys.readouterr().err
    assert not out.exists()


def test_the_table_has_one_block_per_n() -> None:
    lines = {"lqr": {1: [3.24], 2: [0.36, -6.69]}, "x": {1: "refused: no", 2: [1.0, 2.0]}}
    assert markdown(lines, [1, 2]).splitlines() == [
        "n = 1",
        "",
        "| policy | g_1 |",
        "|---|---|",
        "| lqr | 3.24 |",
        "| x | - |",
        "",
        "n = 2",
        "",
        "| policy | g_1 | g_2 |",
        "|---|---|---|",
        "| lqr | 0.36 | -6.69 |",
        "| x | 1 | 2 |",
    ]
