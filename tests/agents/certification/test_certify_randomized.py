"""Certifying randomised physics: each start's drawn parameters are planned with and replayed."""

from __future__ import annotations

import json
import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from agents.artifacts.action_records import read_actions
from agents.artifacts.certificates import (
    FEASIBLE,
    OPEN,
    Certificate,
    CertificateEnv,
    CertificateStart,
    Certified,
    PlannerPart,
    ScreenPart,
    actions_path,
    certificate_path,
    committed_actions,
    committed_certificate,
    markdown,
    read_certificate,
    write_certificate,
)
from agents.certification.certify import certify, replay
from agents.certification.witnesses import add_witnesses, default_witnesses
from agents.commands.certify import main
from agents.oracles.planner import PlannerConfig

V1 = "trailer_env/Reverse-v1"
DOCK = "trailer_env/Dock-v0"
SMALL = PlannerConfig(samples=4, elites=1, iterations=1, tail=30)
SEEDS = [1000, 1001, 1002]
RANDOMIZED = {"n_trailers": 1, "randomize": "mismatch20"}


@pytest.fixture(scope="module")
def certified() -> Certified:
    return certify(V1, 1, SEEDS, SMALL, restarts=0, randomize="mismatch20")


def _drawn(seed: int) -> dict[str, float]:
    env = gym.make(V1, **RANDOMIZED)
    _, info = env.reset(seed=seed)
    env.close()
    return dict(info["params"])


def test_the_certificate_records_the_randomisation(certified: Certified) -> None:
    certificate = certified.certificate
    assert certificate.env_kwargs.kwargs() == RANDOMIZED
    block = certificate.randomize
    assert block is not None and block.preset == "mismatch20"
    assert block.ranges == {name: (0.8, 1.2) for name in ("M", "J0", "a", "l", "mu")}
    assert [start.status for start in certificate.starts] == [FEASIBLE, FEASIBLE, OPEN]
    counts = certificate.feasible, certificate.open, certificate.not_recoverable
    assert counts == (2, 1, 0)
    text = markdown(certificate)
    assert text.startswith(f"# {V1}, n = 1, seeds 1000-1002, randomize=mismatch20\n")
    assert "randomised physics (M x 0.8-1.2, J0 x 0.8-1.2, a x 0.8-1.2" in text


def test_each_start_keeps_the_parameters_a_fresh_env_draws(certified: Certified) -> None:
    nominal = _nominal_params()
    for start in certified.certificate.starts:
        drawn = _drawn(start.seed)
        assert start.params == drawn
        # The draws moved every randomised parameter away from nominal physics.
        assert all(drawn[name] != nominal[name] for name in ("M", "J0", "a", "l", "mu"))
        assert (drawn["m"], drawn["J"], drawn["speed_factor"]) == (1.0, 0.1, 1.0)


def _nominal_params() -> dict[str, float]:
    env = gym.make(V1, n_trailers=1)
    params = env.unwrapped.settings.params
    env.close()
    return {name: float(getattr(params, name)) for name in ("M", "J0", "a", "l", "mu")}


def test_the_records_replay_under_the_drawn_physics_only(certified: Certified) -> None:
    assert sorted(certified.actions) == [1000, 1001]
    for seed, record in certified.actions.items():
        assert record.dtype == np.float64 and record.shape == (400,)
        randomized = replay(V1, RANDOMIZED, seed, record)
        assert (randomized.safe, randomized.length) == (True, 400)
        # The same record under nominal physics is another experiment: it folds early.
        nominal = replay(V1, {"n_trailers": 1}, seed, record)
        assert not nominal.safe and nominal.length < 200


def test_the_files_round_trip(certified: Certified, tmp_path: Path) -> None:
    write_certificate(certified, tmp_path / "cert", overwrite=False)
    document = read_certificate(tmp_path / "cert" / "certificate.json")
    assert document.env_kwargs.kwargs() == RANDOMIZED
    assert [start.params for start in document.starts] == [_drawn(seed) for seed in SEEDS]
    records = read_actions(tmp_path / "cert" / "actions.npz")
    for seed in (1000, 1001):
        assert records[seed].reshape(-1).tobytes() == certified.actions[seed].tobytes()


def test_a_committed_randomised_certificate_is_found_by_its_preset(
    certified: Certified, tmp_path: Path
) -> None:
    write_certificate(certified, tmp_path / "out", overwrite=False)
    folder = tmp_path / "certificates"
    folder.mkdir()
    named = certificate_path(V1, 1, folder, randomize="mismatch20")
    assert named.name == "reverse_v1_mismatch20_n1.json"
    named.write_bytes((tmp_path / "out" / "certificate.json").read_bytes())
    records = actions_path(V1, 1, folder, randomize="mismatch20")
    assert records.name == "reverse_v1_mismatch20_n1_actions.npz"
    records.write_bytes((tmp_path / "out" / "actions.npz").read_bytes())
    found = committed_certificate(V1, 1, folder, randomize="mismatch20")
    assert found is not None and found.env_kwargs.kwargs() == RANDOMIZED
    assert committed_certificate(V1, 1, folder) is None  # nominal physics: another file
    loaded = committed_actions(V1, 1, folder, randomize="mismatch20")
    assert loaded is not None and sorted(loaded) == [1000, 1001]
    # A randomised certificate under the nominal name is refused, not read as nominal.
    certificate_path(V1, 1, folder).write_bytes(named.read_bytes())
    with pytest.raises(ValueError, match="with n = 1 and nominal physics"):
        committed_certificate(V1, 1, folder)


def test_witnesses_play_under_the_same_randomisation(certified: Certified) -> None:
    upgraded = add_witnesses(certified, ["lqr", "lqr-adaptive"], closed_loop=False)
    witnesses = upgraded.certificate.witnesses
    assert witnesses is not None
    assert [(run.source, run.tried, run.solved) for run in witnesses.runs] == WITNESS_RUNS
    assert upgraded.certificate.env_kwargs.kwargs() == RANDOMIZED
    for seed, record in upgraded.actions.items():
        outcome = replay(V1, RANDOMIZED, seed, record)
        assert (outcome.safe, outcome.length) == (True, 400)


#: What lqr and lqr-adaptive do on the start the small planner left open (1002).
WITNESS_RUNS = [("lqr", 1, 0), ("lqr-adaptive", 1, 0)]


def test_a_witness_is_rechecked_closed_loop_on_an_rk4_plant_with_the_drawn_physics() -> None:
    starts = tuple(
        CertificateStart(seed=seed, status=OPEN, screen_stroke_fraction=None,
                         planner_safe=False, planner_length=0)
        for seed in SEEDS
    )  # fmt: skip
    nothing = PlannerPart(horizon=0, iterations=0, restarts=0, first_pass_safe=0,
                          first_pass_wall_time_s=0.0, simulated_steps_per_episode=0.0,
                          wall_time_s=0.0)  # fmt: skip
    certificate = Certificate(
        env_id=V1, env_kwargs=CertificateEnv(n_trailers=1, randomize="mismatch20"),
        seeds=(1000, 1002), episodes=3, planner=nothing, screen=ScreenPart(wall_time_s=0.0),
        feasible=0, not_recoverable=0, open=3, ceiling=0.0, screen_upper_estimate=1.0,
        starts=starts,
    )  # fmt: skip
    upgraded = add_witnesses(Certified(certificate, {}), ["lqr", "lqr-adaptive"])
    assert [start.source for start in upgraded.certificate.starts] == ["lqr", "lqr", None]
    witnesses = upgraded.certificate.witnesses
    assert witnesses is not None and witnesses.closed_loop is not None
    closed = witnesses.closed_loop
    # dopri5 integrates one parameter vector per batch: the drawn physics need RK4.
    assert (closed.integrator, closed.tolerance) == ("rk4", 1e-8)
    assert (closed.success, closed.of) == (2, 2)


def test_the_default_witnesses_add_the_adaptive_regulator() -> None:
    nominal = [Path(spec).stem for spec in default_witnesses(V1, 2)]
    randomized = [Path(spec).stem for spec in default_witnesses(V1, 2, randomized=True)]
    assert nominal[:3] == ["zero", "random", "lqr"] and "lqr-adaptive" not in nominal
    assert randomized == [*nominal[:3], "lqr-adaptive", *nominal[3:]]


def test_randomize_is_validated_before_anything_runs() -> None:
    supported = r"mpc\) on trailer_env/Reverse-v0, trailer_env/Reverse-v1"
    with pytest.raises(ValueError, match=supported):
        certify(DOCK, 1, [1000], SMALL, randomize="mismatch20")
    with pytest.raises(ValueError, match="unknown preset 'mismatch50'"):
        certify(V1, 1, [1000], SMALL, randomize="mismatch50")
    with pytest.raises(TypeError, match="randomize must be None, a preset name or a dict"):
        certify(V1, 1, [1000], SMALL, randomize=0.2)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--env", DOCK, "--randomize", "mismatch20"], "not for trailer_env/Dock-v0"),
        (
            ["--randomize", "mismatch50"],
            r"expected a preset \(mismatch10, mismatch20, mismatch30, mismatch40\) or a JSON",
        ),
        (["--randomize", '{"mu": [1.2, 0.8]}'], r"randomize\['mu'\] = \(1.2, 0.8\): low > high"),
        (["--randomize", '{"b": [0.9, 1.1]}'], "unknown name"),
        (["--randomize", '{"mu": ' * 70 + "1" + "}" * 70], "nested 70 deep, over the limit"),
    ],
)
def test_a_refused_randomisation_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    out = tmp_path / "cert"
    with pytest.raises(SystemExit) as error:
        main([*argv, "--n-trailers", "1", "--seeds", "1000", "--out", str(out)])
    assert error.value.code == 2
    err = capsys.readouterr().err
    assert "argument --randomize" in err and re.search(message, err)
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_the_command_writes_a_randomised_certificate(tmp_path: Path) -> None:
    out = tmp_path / "cert"
    argv = ["--n-trailers", "1", "--seeds", "1000-1001", "--randomize", '{"mu": [0.8, 1.2]}',
            "--samples", "4", "--iterations", "1", "--no-witnesses", "--restarts", "0",
            "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    document = json.loads((out / "certificate.json").read_text())
    assert document["env_kwargs"] == {"n_trailers": 1, "randomize": {"mu": [0.8, 1.2]}}
    assert document["randomize"]["preset"] is None
    for start in document["starts"]:
        env = gym.make(V1, n_trailers=1, randomize={"mu": [0.8, 1.2]})
        _, info = env.reset(seed=start["seed"])
        assert start["params"] == info["params"]
        assert info["params"]["M"] == 1.0  # only mu is drawn
