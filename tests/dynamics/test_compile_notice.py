"""The one line printed before this project's first kernel compiles in a process."""

from __future__ import annotations

import numba
import pytest

from dynamics import _notice


def _function(module: str, factor: float) -> numba.core.dispatcher.Dispatcher:
    def scaled(x: float) -> float:
        return x * factor

    scaled.__module__ = module  # as if defined in that package: the listener reads it
    return numba.njit(scaled)


def test_the_notice_is_printed_once_per_process(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(_notice.LISTENER, "printed", False)
    assert _function("trailer_env.probe", 2.0)(1.5) == 3.0
    assert _function("dynamics.probe", 3.0)(1.5) == 4.5
    assert _function("agents.probe", 4.0)(1.5) == 6.0
    captured = capsys.readouterr()
    assert captured.err == _notice.NOTICE + "\n"
    assert captured.out == ""
    assert _notice.NOTICE == (
        "trailer-env: compiling kernels once, about a minute; `trailer-env --compile` does it ahead"
    )


def test_other_packages_compiles_print_nothing(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(_notice.LISTENER, "printed", False)
    assert _function("somebody_else", 2.0)(2.0) == 4.0
    assert capsys.readouterr().err == ""
    assert _notice.LISTENER.printed is False


def test_kernels_loaded_from_the_disk_cache_print_nothing() -> None:
    import subprocess
    import sys

    script = (
        "import gymnasium as gym, trailer_env\n"
        "env = gym.make('trailer_env/Reverse-v1')\n"
        "env.reset(seed=0)\n"
        "env.step(env.action_space.sample())\n"
    )
    runs = [
        subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
        for _ in range(2)
    ]
    # The first run may fill the cache (a fresh clone); the second only loads from it.
    assert runs[0].stderr.count(_notice.NOTICE) <= 1
    assert _notice.NOTICE not in runs[1].stderr
