"""Compiling the kernels ahead of the first run (numba's disk cache).

The compiled kernels are cached on disk beside their modules the first time they run
(:func:`dynamics.jit.cached_njit`), which makes the very first step of a fresh install take many
seconds. :func:`compile_kernels` runs every scene's step once for each variant the
commands use (without and with the plane pose; the serial and the parallel batch
kernel) so that the set-up command pays for it once; ``python -m trailer_env
--compile`` calls it, and ``scripts/install.sh`` runs that.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from trailer_env.episodes import count_episodes, count_step
from trailer_env.kernels import PARALLEL_MIN_ROWS
from trailer_env.registry import ENVIRONMENTS, core_class_of
from trailer_env.settings import settings_from_kwargs
from trailer_env.vector import seed_generators


def _compile_bookkeeping() -> None:
    """The vector env's and the SB3 adapter's per-step counters (:mod:`trailer_env.episodes`)."""
    elapsed, flags = np.zeros(1, dtype=np.int64), np.zeros(1, dtype=bool)
    count_step(elapsed, 1, flags, flags.copy(), flags.copy())
    count_episodes(
        elapsed,
        1,
        flags,
        np.zeros(1, dtype=np.float32),
        np.zeros(1),
        np.zeros(1, dtype=np.int64),
        flags.copy(),
        flags.copy(),
    )


def compile_kernels(report: Callable[[str], None] = print) -> float:
    """Step each scene once per kernel variant; returns the wall time (s).

    ``report`` receives one line per scene.
    """
    started = time.perf_counter()
    settings = settings_from_kwargs()
    for env_id in ENVIRONMENTS:
        began = time.perf_counter()
        core_class = core_class_of(env_id)
        for rows, track_pose in ((2, False), (2, True), (PARALLEL_MIN_ROWS, False)):
            core = core_class(settings, rows, track_pose=track_pose)
            core.reset_rows(np.arange(rows), seed_generators(0, rows, None))
            core.step(np.zeros((rows, settings.action_dim)))
        report(f"compiled {env_id} in {time.perf_counter() - began:.1f} s")
    _compile_bookkeeping()
    return time.perf_counter() - started
