"""Training-seed siblings of committed models, the spread column, and the ceiling line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from agents.artifacts.cards import ModelCard
from agents.artifacts.certificates import committed_certificate
from agents.artifacts.results import Summary
from agents.artifacts.shipped import seed_models
from agents.evaluation.ceiling import ceiling_note
from agents.evaluation.metrics import EpisodeResults, summary_of
from agents.evaluation.results import Evaluation
from agents.evaluation.tables import seeds_note, training_note
from tests.agents.helpers import fake_certified

V1 = "trailer_env/Reverse-v1"


def _results(safe: list[bool]) -> EpisodeResults:
    count = len(safe)
    ok = np.array(safe)
    return EpisodeResults(
        seeds=np.arange(count),
        returns=np.zeros(count),
        lengths=np.full(count, 400),
        jackknifed=~ok,
        success=ok,
        failed=~ok,
        band_steps=np.zeros(count, dtype=np.int64),
        min_margin=np.ones(count),
        actuator_work=np.zeros(count),
        margins=np.ones(count),
    )


def test_seed_models_are_the_numbered_siblings(tmp_path: Path) -> None:
    seeds = tmp_path / "seeds"
    seeds.mkdir()
    for name in ("x_s0", "x_s1", "x_s10", "x_sfoo", "x_s2_old", "y_s0"):
        (seeds / f"{name}.zip").write_bytes(b"")
    found = seed_models(str(tmp_path / "x.zip"), directory=seeds)
    assert [path.stem for path in found] == ["x_s0", "x_s1", "x_s10"]
    # A model of the same name elsewhere (a retrained one) is not the committed model.
    assert seed_models(str(tmp_path / "elsewhere" / "x.zip"), directory=seeds) == []
    assert seed_models("lqr", directory=seeds) == []


def test_seeds_note_reports_mean_sd_and_range() -> None:
    summary = summary_of(_results([True]))
    summaries: list[tuple[int | None, Summary]] = [
        (seed, summary.replace(safe_rate=rate)) for seed, rate in ((0, 0.94), (1, 0.96), (2, 0.98))
    ]
    evaluation = Evaluation("m", "m.zip", ModelCard(), _results([True]), None, summaries)
    mean, sd, low, high = evaluation.seed_spread() or (0, 0, 0, 0)
    assert mean == pytest.approx(0.96) and sd == pytest.approx(np.std([0.94, 0.96, 0.98]))
    assert (low, high) == (0.94, 0.98)
    assert seeds_note(evaluation) == "96 ± 2 (94-98, 3 seeds)"
    assert seeds_note(Evaluation("lqr", "lqr", ModelCard(), _results([True]))) == "-"
    assert training_note(ModelCard(), "mpc").startswith("oracle")
    card: dict[str, object] = {
        "algo": "ppo",
        "recipe": "dagger",
        "seed": 1,
        "timesteps": 614_400,
        "selected_at_iteration": 3,
        "wall_time_s": 500,
    }
    assert training_note(ModelCard.from_json(card)) == (
        "PPO policy by DAgger from mpc, seed 1, 0.614M labels (kept iteration 3), 500 s"
    )
    assert training_note(ModelCard.from_json({**card, "expert": "ilqr"})) == (
        "PPO policy by DAgger from ilqr, seed 1, 0.614M labels (kept iteration 3), 500 s"
    )


def _certificate(folder: Path, statuses: list[str], env_id: str = V1, n: int = 2) -> None:
    seeds = [1000 + i for i in range(len(statuses))]
    certificate = fake_certified(seeds, env_id, n, status="open").certificate
    starts = tuple(
        start.replace(status=status)
        for start, status in zip(certificate.starts, statuses, strict=True)
    )
    folder.mkdir(exist_ok=True)
    document = certificate.with_starts(starts).to_json()
    (folder / "reverse_v1_n2.json").write_text(json.dumps(document))


def test_ceiling_note_counts_the_evaluated_starts(tmp_path: Path) -> None:
    _certificate(tmp_path, ["feasible", "open", "feasible", "not recoverable"])
    note = ceiling_note(V1, 2, 4, 1000, directory=tmp_path)
    assert note.startswith("ceiling: 2/4 starts certified feasible")
    assert "1 not recoverable (screen), 1 open" in note
    assert ceiling_note(V1, 2, 1, 1002, directory=tmp_path).startswith("ceiling: 1/1")
    outside = ceiling_note(V1, 2, 4, 1002, directory=tmp_path)
    assert "certified on seeds 1000-1003 (50% feasible), not on these episodes" in outside
    assert "not certified" in ceiling_note(V1, 3, 4, 1000, directory=tmp_path)


def test_a_certificate_of_another_scene_is_refused(tmp_path: Path) -> None:
    _certificate(tmp_path, ["feasible"], env_id="trailer_env/Reverse-v0")
    with pytest.raises(ValueError, match="not a certificate of trailer_env/Reverse-v1"):
        committed_certificate(V1, 2, directory=tmp_path)
    (tmp_path / "reverse_v1_n2.json").write_text("{")
    with pytest.raises(ValueError, match="not JSON"):
        committed_certificate(V1, 2, directory=tmp_path)


def test_committed_certificates_meet_the_ceiling_targets() -> None:
    for n in (1, 2, 3):
        certificate = committed_certificate(V1, n)
        assert certificate is not None, n
        assert certificate.episodes == 100 and certificate.seeds == (1000, 1099)
        assert certificate.feasible >= 99, n
        strokes = [start.screen_stroke_fraction for start in certificate.starts]
        assert all(stroke is not None and stroke <= 0.8 for stroke in strokes), n


def test_env_keywords_reach_the_episodes_and_the_json(tmp_path: Path) -> None:
    from agents.commands import evaluate as command

    out = tmp_path / "heavy"
    argv = ["--policy", "lqr", "--set", "M=1.2", "--set", "fidelity=dopri5"]
    assert command.main([*argv, "--episodes", "6", "--no-plots", "--out", str(out)]) == 0
    document = json.loads((out / "results.json").read_text())
    assert document["env_kwargs"] == {"n_trailers": 2, "M": 1.2, "fidelity": "dopri5"}
    nominal = tmp_path / "nominal"
    assert (
        command.main(["--policy", "lqr", "--episodes", "6", "--no-plots", "--out", str(nominal)])
        == 0
    )
    other = json.loads((nominal / "results.json").read_text())
    assert other["policies"][0]["mean_return"] != document["policies"][0]["mean_return"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--set", "M=-1"], "argument --set: M must be in [1e-06, 1e+06], got -1"),
        (["--set", "frameskip=2"], "argument --set: unexpected keyword argument 'frameskip'"),
        (["--set", "n_trailers=3"], "argument --set: give n_trailers with --n-trailers"),
        (["--set", "M"], "argument --set: expected KEY=VALUE, got 'M'"),
        (["--set", "M=1", "--set", "M=2"], "argument --set: M given twice"),
        (["--policy", "mpc-replay", "--set", "M=1.2"], "default settings only"),
    ],
)
def test_bad_env_keywords_exit_2_before_any_episode(
    argv: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from agents.commands import evaluate as command

    with pytest.raises(SystemExit) as raised:
        command.main([*argv, "--out", str(tmp_path / "out")])
    assert raised.value.code == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
