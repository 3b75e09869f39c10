"""python -m agents.across_n: the rate against n, with empty cells where a policy refuses n."""

from __future__ import annotations

import json
from argparse import ArgumentTypeError
from pathlib import Path

import pytest

from agents.commands.across_n import main
from agents.commands.options import trailer_list
from agents.evaluation.across_n import CEILING, SPECIALIST, markdown, rates_across_n


def test_counts_and_the_table_of_empty_cells() -> None:
    assert trailer_list("1-6") == [1, 2, 3, 4, 5, 6] and trailer_list("4,2,2") == [2, 4]
    assert trailer_list("1-2,6") == [1, 2, 6]
    for bad, why in (("0-3", "in 1..16"), ("1-17", "in 1..16"), ("a", "LOW-HIGH"), ("", "nothing")):
        with pytest.raises(ArgumentTypeError, match=why):
            trailer_list(bad)
    lines = {"lqr": {1: 0.91, 4: 0.5}, SPECIALIST: {1: 1.0, 4: "no model x_n4"}}
    assert markdown(lines, [1, 4]).splitlines()[2:] == [
        "| lqr | 91 | 50 |",
        f"| {SPECIALIST} | 100 | - |",
    ]


def test_the_command_writes_table_json_and_chart(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "across"
    args = [
        "--n",
        "1-2",
        "--policy",
        "zero",
        "--specialist",
        "dagger_reverse_v1_n{n}",
        "--episodes",
        "3",
        "--out",
        str(out),
    ]
    assert main(args) == 0
    document = json.loads((out / "across_n.json").read_text())
    lines = document["lines"]
    assert lines["zero"] == {"1": 0.0, "2": 0.0}  # the zero action folds every convoy
    assert lines[CEILING] == {"1": 1.0, "2": 1.0}  # the certificates' test starts 1000-1002
    assert all(isinstance(rate, float) for rate in lines[SPECIALIST].values())
    assert (out / "across_n.png").stat().st_size > 10_000
    assert "| zero | 0 | 0 |" in (out / "across_n.md").read_text()
    with pytest.raises(SystemExit) as refused:
        main(args)  # the files exist: refused without --overwrite, nothing rewritten
    assert refused.value.code == 2 and "pass --overwrite" in capsys.readouterr().err
    with pytest.raises(SystemExit) as refused:
        main([*args[:4], "--specialist", "dagger_reverse_v1_n2", "--out", str(tmp_path / "b")])
    assert refused.value.code == 2 and not (tmp_path / "b").exists()
    with pytest.raises(SystemExit) as refused:
        main([*args[:4], "--specialist", "a{n},b{n}", "--out", str(tmp_path / "c")])
    assert refused.value.code == 2 and not (tmp_path / "c").exists()
    assert "more than one item without counts" in capsys.readouterr().err


def test_a_list_of_specialists_takes_each_counts_own() -> None:
    lines = rates_across_n(
        "trailer_env/Reverse-v1",
        [1, 2, 3],
        ["zero"],
        "1=ppo_reverse_v1_n{n},2=dagger_reverse_v1_n{n}",
        2,
        1000,
    )
    direct = rates_across_n("trailer_env/Reverse-v1", [1], ["ppo_reverse_v1_n1"], None, 2, 1000)
    assert lines[SPECIALIST][1] == direct["ppo_reverse_v1_n1"][1]
    assert isinstance(lines[SPECIALIST][2], float)
    assert (
        lines[SPECIALIST][3]
        == "no specialist of n = 3 in 1=ppo_reverse_v1_n{n},2=dagger_reverse_v1_n{n}"
    )
