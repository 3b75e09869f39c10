"""``python -m trailer_env``: the list, and --play's refusals (exit 2, before any window)."""

from __future__ import annotations

import pytest

import trailer_env
from trailer_env.__main__ import main


def test_the_list_names_every_id(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([]) == 0
    printed = capsys.readouterr().out
    assert "trailer_env/Reverse-v1" in printed and " 400 steps" in printed


@pytest.mark.parametrize(
    ("argv", "environment", "message"),
    [
        (
            ["--play", "trailer_env/Reverse-v1"],
            {"DISPLAY": None, "WAYLAND_DISPLAY": None},
            "argument --play: needs a display",
        ),
        (
            ["--play", "trailer_env/Reverse-v1"],
            {"DISPLAY": ":0", "SDL_VIDEODRIVER": "dummy"},
            "argument --play: needs a display",
        ),
        (
            ["--play", "trailer_env/Reverse-v1", "--n-trailers", "300"],
            {"DISPLAY": ":0"},
            "argument --n-trailers: n_trailers must be an integer in [0, 256], got 300",
        ),
        (["--play", "trailer_env/Reverse-v1", "--seed", "-1"], {}, "argument --seed: must be in"),
        (["--play", "trailer_env/Nope-v0"], {}, "unknown environment 'trailer_env/Nope-v0'"),
    ],
)
def test_play_refuses_what_cannot_work(
    argv: list[str],
    environment: dict[str, str | None],
    message: str,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    for key, value in environment.items():
        if value is None:
            monkeypatch.delenv(key, raising=False)
        else:
            monkeypatch.setenv(key, value)
    with pytest.raises(SystemExit) as raised:
        main(argv)
    assert raised.value.code == 2
    assert message in capsys.readouterr().err


def test_compile_steps_every_scene(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--compile"]) == 0
    printed = capsys.readouterr().out
    assert printed.count("compiled trailer_env/") == len(trailer_env.ENVIRONMENTS) >= 1
    assert all(f"compiled {env_id}" in printed for env_id in trailer_env.ENVIRONMENTS)
    assert "compiled every kernel in" in printed
