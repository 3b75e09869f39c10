"""Each command writes its own default folder: documented commands run one after another
do not meet in one folder."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents.commands import certify, evaluate, main, options, report, tune

V1 = "trailer_env/Reverse-v1"


def _default(parser_of: object, dest: str = "out") -> object:
    parser = parser_of.build_parser()  # type: ignore[attr-defined]
    return parser.get_default(dest)


def test_every_output_folder_default_is_the_commands_own() -> None:
    assert _default(main) == Path("out/main")
    assert _default(report) == Path("out/report")
    # certify, evaluate and tune name their folder from what they run (None: computed).
    assert _default(certify) is None and _default(evaluate) is None and _default(tune) is None
    for module in (certify, evaluate, main, report):
        text = module.build_parser().format_help()
        assert "default out/" in " ".join(text.split()), module.__name__


def test_the_evaluation_folder_names_the_scene_the_policies_and_the_settings() -> None:
    root = Path("out/evaluate")
    assert evaluate.default_out(V1, {"n_trailers": 2}, None) == root / "reverse_v1_n2"
    assert evaluate.default_out(V1, {"n_trailers": 2}, ["lqr", "dagger_reverse_v1_n2"]) == (
        root / "reverse_v1_n2_lqr_dagger_reverse_v1_n2"
    )
    physics = {"n_trailers": 3, "randomize": "mismatch20", "M": 1.2}
    assert evaluate.default_out(V1, physics, ["lqr"]).name == (
        "reverse_v1_n3_lqr_randomize=mismatch20_M=1.2"
    )
    long_a = evaluate.default_out(V1, {"n_trailers": 2}, ["a" * 150])
    long_b = evaluate.default_out(V1, {"n_trailers": 2}, ["a" * 151])
    assert len(long_a.name) <= options.MAX_FOLDER_NAME and long_a != long_b


@pytest.mark.parametrize(
    ("parts", "name"),
    [
        (("reverse_v1_n2", "my_module:act"), "reverse_v1_n2_my_module-act"),
        (("x", "", "y/z"), "x_y-z"),
        (("../..",), "default"),
        (('fidelity={"tolerance":1e-06}',), "fidelity=-tolerance-1e-06"),
    ],
)
def test_folder_names_keep_to_safe_characters(parts: tuple[str, ...], name: str) -> None:
    assert options.folder_name(*parts) == name


@pytest.mark.slow
def test_two_documented_evaluations_in_a_row_write_two_folders(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    base = ["--env", V1, "--n-trailers", "2", "--episodes", "2", "--no-plots"]
    assert evaluate.main([*base, "--policy", "zero"]) == 0
    assert evaluate.main([*base, "--policy", "lqr"]) == 0
    written = sorted(path.parent.name for path in tmp_path.glob("out/evaluate/*/results.json"))
    assert written == ["reverse_v1_n2_lqr", "reverse_v1_n2_zero"]
    document = json.loads((tmp_path / "out/evaluate/reverse_v1_n2_lqr/results.json").read_text())
    assert [row["name"] for row in document["policies"]] == ["lqr"]
