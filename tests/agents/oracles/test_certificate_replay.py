"""A certificate's own action records are replayed before ``--from-certificate`` passes them on."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from agents.artifacts.action_records import read_actions, write_actions
from agents.artifacts.certificates import (
    CERTIFICATES_DIR,
    FEASIBLE,
    Certified,
    read_certificate,
    records_beside,
)
from agents.certification.replays import check_records
from agents.commands.certify import DEFAULT_OUT_ROOT, default_out, load_certificate, main

#: Every committed certificate file.
COMMITTED = sorted(CERTIFICATES_DIR.glob("*.json"))
#: A small one (Reverse-v0, n = 3: 25 feasible starts, under a second to replay).
SMALL = CERTIFICATES_DIR / "reverse_n3.json"


def _copy(source: Path, folder: Path) -> Path:
    """The certificate ``source`` and its records, copied into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copy(source, folder / source.name)
    shutil.copy(records_beside(source), records_beside(folder / source.name))
    return folder / source.name


def _statuses(path: Path) -> dict[int, str]:
    return {start.seed: start.status for start in read_certificate(path).starts}


def _refused(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    with pytest.raises(SystemExit) as raised:
        main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert raised.value.code == 2, err
    return err[-1]


def _check_loads_and_replays(path: Path) -> None:
    loaded = load_certificate(path)
    starts = loaded.certificate.starts
    assert {start.seed: start.status for start in starts} == _statuses(path)
    feasible = {start.seed for start in starts if start.status == FEASIBLE}
    assert set(loaded.actions) == feasible and len(feasible) == loaded.certificate.feasible


def test_a_committed_certificate_loads_and_replays_to_its_statuses() -> None:
    _check_loads_and_replays(SMALL)
    assert read_certificate(SMALL).feasible == 25


@pytest.mark.parametrize(("n", "feasible"), [(7, 97), (8, 100)])
def test_the_seven_and_eight_trailer_certificates_replay_to_their_outcome(
    n: int, feasible: int
) -> None:
    path = CERTIFICATES_DIR / f"reverse_v1_n{n}.json"
    _check_loads_and_replays(path)
    certificate = read_certificate(path)
    assert (certificate.feasible, certificate.not_recoverable) == (feasible, 0)
    # The hardest test start needs 0.80 (n = 7) and 0.86 (n = 8) of the stroke.
    assert max(start.screen_stroke_fraction or 0.0 for start in certificate.starts) < 0.9


@pytest.mark.slow
@pytest.mark.parametrize("path", COMMITTED, ids=[path.stem for path in COMMITTED])
def test_every_committed_certificate_loads_and_replays_to_its_statuses(path: Path) -> None:
    _check_loads_and_replays(path)


def test_a_replaced_record_is_refused_naming_its_start(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _copy(SMALL, tmp_path / "cert")
    records = read_actions(records_beside(path))
    victim = sorted(records)[3]
    records[victim] = np.full_like(records[victim], 0.25)  # a constant action, same length
    write_actions(records, records_beside(path))
    out = tmp_path / "out"
    line = _refused(["--from-certificate", str(path), "--out", str(out)], capsys)
    assert f"the record of start {victim} does not replay to its stated outcome" in line
    assert not out.exists()


def test_a_record_of_a_start_that_is_not_feasible_is_refused(tmp_path: Path) -> None:
    path = _copy(SMALL, tmp_path / "cert")
    records = read_actions(records_beside(path))
    other = next(seed for seed, status in _statuses(path).items() if status != FEASIBLE)
    records[other] = next(iter(records.values()))
    write_actions(records, records_beside(path))
    with pytest.raises(ValueError, match=rf"records of starts that are not feasible \[{other}\]"):
        load_certificate(path)


def test_a_dock_certificate_relabelled_as_reverse_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _copy(CERTIFICATES_DIR / "dock_n1.json", tmp_path / "cert")
    document = json.loads(path.read_text())
    document["env_id"] = "trailer_env/Reverse-v1"
    path.write_text(json.dumps(document))
    out = tmp_path / "out"
    line = _refused(["--from-certificate", str(path), "--out", str(out)], capsys)
    first = min(start["seed"] for start in document["starts"] if start["status"] == FEASIBLE)
    assert f"the record of start {first} does not replay" in line
    assert "trailer_env/Reverse-v1" in line and not out.exists()


def test_stated_parameters_that_the_env_does_not_draw_are_refused(tmp_path: Path) -> None:
    path = _copy(CERTIFICATES_DIR / "reverse_v1_mismatch20_n2.json", tmp_path / "cert")
    document = json.loads(path.read_text())
    start = document["starts"][5]
    start["params"]["M"] = start["params"]["M"] * 1.01
    path.write_text(json.dumps(document))
    with pytest.raises(ValueError, match=f"start {start['seed']} states parameters"):
        load_certificate(path)


@pytest.mark.parametrize("cut", [0, 100, -10])
def test_a_cut_records_archive_is_one_line_and_exit_2(
    tmp_path: Path, cut: int, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _copy(SMALL, tmp_path / "cert")
    archive = records_beside(path)
    data = archive.read_bytes()
    archive.write_bytes(data[:cut])
    out = tmp_path / "out"
    line = _refused(["--from-certificate", str(path), "--out", str(out)], capsys)
    assert "is not an action-record archive (cut or damaged?)" in line and not out.exists()


def test_a_damaged_records_archive_is_refused(tmp_path: Path) -> None:
    path = _copy(SMALL, tmp_path / "cert")
    archive = records_beside(path)
    data = bytearray(archive.read_bytes())
    data[len(data) // 2] ^= 0xFF  # inside a compressed record: a bad CRC or deflate stream
    archive.write_bytes(bytes(data))
    with pytest.raises(ValueError, match="not an action-record archive"):
        load_certificate(path)


@pytest.mark.parametrize("seeds", ["", " ", ","])
def test_no_seeds_are_refused(
    seeds: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    line = _refused(["--seeds", seeds, "--out", str(out)], capsys)
    assert "argument --seeds" in line and not out.exists()


def test_the_default_out_is_the_certificates_own_folder() -> None:
    v1, dock = "trailer_env/Reverse-v1", "trailer_env/Dock-v0"
    assert default_out(v1, 2, None, witnessed=False) == DEFAULT_OUT_ROOT / "reverse_v1_n2"
    assert default_out(v1, 3, "mismatch20", witnessed=False) == (
        DEFAULT_OUT_ROOT / "reverse_v1_mismatch20_n3"
    )
    assert default_out(v1, 1, {"mu": [0.8, 1.2]}, witnessed=False).name == (
        "reverse_v1_randomized_n1"
    )
    assert default_out(dock, 1, None, witnessed=True) == DEFAULT_OUT_ROOT / "dock_n1_witnessed"
    assert Path("out/certify") == DEFAULT_OUT_ROOT


def test_the_command_writes_its_default_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = _copy(SMALL, tmp_path / "cert")
    monkeypatch.chdir(tmp_path)
    # A witness that solves nothing (zero folds every Reverse start): the certificate
    # is passed on unchanged, into its default folder.
    assert main(["--from-certificate", str(path), "--witnesses", "zero"]) == 0
    written = tmp_path / "out" / "certify" / "reverse_n3_witnessed" / "certificate.json"
    assert _statuses(written) == _statuses(SMALL)
    assert sorted(read_actions(written.with_name("actions.npz"))) == sorted(
        read_actions(records_beside(SMALL))
    )


def test_check_records_names_a_missing_record() -> None:
    loaded = load_certificate(SMALL)
    first = min(loaded.actions)
    kept = {seed: record for seed, record in loaded.actions.items() if seed != first}
    with pytest.raises(
        ValueError, match=rf"where: no action record of the feasible starts \[{first}\]"
    ):
        check_records(Certified(loaded.certificate, kept), "where")
