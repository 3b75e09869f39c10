"""The one reader of "N-M" ranges (agents.commands.options): bounds as parameters."""

from __future__ import annotations

import argparse

import pytest

from agents.commands.options import (
    argument_type,
    integer_list,
    integer_range,
    trailer_counts,
    trailer_list,
)


def test_a_count_or_a_range_within_the_bounds() -> None:
    assert integer_range("4", 1, 16) == (4, 4)
    assert integer_range(" 1-3 ", 1, 16) == (1, 3)
    assert integer_range("1000-1099", 0, 2**32 - 1) == (1000, 1099)
    assert integer_range("7-7", 0) == (7, 7)  # no upper bound when none is given
    assert trailer_counts("1-3") == (1, 3) and trailer_counts("0") == 0


@pytest.mark.parametrize(
    ("text", "minimum", "maximum", "proper", "message"),
    [
        ("3-1", 0, None, False, "a range LOW-HIGH needs 0 <= LOW <= HIGH, got '3-1'"),
        ("2-2", 0, None, True, "a range LOW-HIGH needs 0 <= LOW < HIGH, got '2-2'"),
        ("0-2", 1, 256, False, "must be in 1..256, got '0-2'"),
        ("1-17", 1, 16, False, "must be in 1..16, got '1-17'"),
        ("-5", 0, None, False, "expected N or a range LOW-HIGH such as 1-3, got '-5'"),
        ("1-", 0, None, False, "expected N or a range LOW-HIGH such as 1-3, got '1-'"),
        ("a-b", 5, 9, False, "expected N or a range LOW-HIGH such as 5-7, got 'a-b'"),
        ("", 0, None, False, "expected N or a range LOW-HIGH"),
    ],
)
def test_a_bad_range_names_what_is_wrong(
    text: str, minimum: int, maximum: int | None, proper: bool, message: str
) -> None:
    with pytest.raises(ValueError, match="^" + message.replace("(", r"\(").replace(".", r"\.")):
        integer_range(text, minimum, maximum, proper=proper)


def test_a_list_of_counts_and_ranges() -> None:
    assert integer_list("1,4-6", 0, 99, max_count=10) == [1, 4, 5, 6]
    assert integer_list("5,1", 0, 99, max_count=10) == [5, 1]  # in the order written
    assert integer_list("1-3,2", 0, 99, max_count=10, distinct=False) == [1, 2, 3, 2]
    for text, message in (
        ("", "nothing given"),
        ("1,1", "an integer appears twice in '1,1'"),
        ("0-10", "more than 10 integers in '0-10'"),
        ("1,,2", "expected N or a range LOW-HIGH"),
    ):
        with pytest.raises(ValueError, match=message):
            integer_list(text, 0, 99, max_count=10)
    # the count is checked before any list is built: a range of 2**32 seeds is refused at once
    with pytest.raises(ValueError, match="more than 10,000 integers"):
        integer_list(f"0-{2**32 - 1}", 0, 2**32 - 1, max_count=10_000)


def test_argparse_types_exit_2_with_the_message() -> None:
    parser = argparse.ArgumentParser(prog="p")
    parser.add_argument("--n", type=trailer_list)
    parser.add_argument(
        "--seeds", type=argument_type(lambda t: integer_list(t, 0, 9, max_count=5), "seeds")
    )
    assert parser.parse_args(["--n", "4,2,2-3", "--seeds", "1-2"]).n == [2, 3, 4]
    for argv, message in (
        (["--n", "0-3"], "counts of trailers: must be in 1..16, got '0-3'"),
        (["--seeds", "1-9"], "more than 5 integers in '1-9'"),
    ):
        with pytest.raises(argparse.ArgumentError, match=message):
            parser.exit_on_error = False
            parser.parse_args(argv)
