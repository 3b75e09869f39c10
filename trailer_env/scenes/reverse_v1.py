"""Reverse-v1: Reverse with a start distribution every start of which is recoverable."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from trailer_env.scenes.reverse import ReverseCore, ReverseEnv

#: Starting reversing speed range, m/s (the stroke needed is smallest near 1-1.2 m/s).
SPEED_RANGE = (0.9, 1.2)
#: Half-widths of the starting hitch angles (rad) and turning rate (rad/s) for one trailer.
ANGLE_NOISE = 0.05
OMEGA_NOISE = 0.05
#: The half-widths shrink as n**-NOISE_EXPONENT: the stroke needed per unit of
#: perturbation grows about that fast with the number of trailers.
NOISE_EXPONENT = 1.2
#: Minimum reversing speed, m/s: the episode fails when -u drops below it.
MIN_REVERSE_SPEED = 0.3


class ReverseV1Core(ReverseCore):
    """Batched task logic of Reverse-v1: slower, smaller starts and a minimum reversing speed."""

    version = 1
    baselines = ("zero", "random", "lqr", "mpc")
    #: Starting reversing speed range (m/s) and the half-widths of the perturbations.
    speed_range: ClassVar[tuple[float, float]] = SPEED_RANGE
    #: Perturbation half-width of one trailer; n trailers: this / n**NOISE_EXPONENT.
    angle_noise: ClassVar[float] = ANGLE_NOISE
    omega_noise: ClassVar[float] = OMEGA_NOISE
    #: The episode fails when the reversing speed -u drops below this (m/s).
    min_reverse_speed: ClassVar[float] = MIN_REVERSE_SPEED

    @classmethod
    def noise_scale(cls, n_trailers: int) -> float:
        """The factor ``max(n, 1) ** -NOISE_EXPONENT`` on the perturbations' half-widths."""
        return float(max(n_trailers, 1) ** -NOISE_EXPONENT)

    def _reset_row(self, i: int, rng: np.random.Generator) -> None:
        z = self.z[i]
        scale = self.noise_scale(self.n)
        z[0] = -rng.uniform(*self.speed_range)
        z[1] = rng.uniform(-self.omega_noise, self.omega_noise) * scale
        z[2 : 2 + self.n] = rng.uniform(-self.angle_noise, self.angle_noise, self.n) * scale

    def _stopped_reversing(self) -> np.ndarray:
        return self.z[:, 0] > -self.min_reverse_speed


class ReverseV1Env(ReverseEnv):
    """Reverse-v1 (docstring written below)."""

    core_class = ReverseV1Core
