"""Reverse-v1: Reverse with a start distribution every start of which is recoverable."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from trailer_env.scenes.reverse import ReverseCore, ReverseEnv

#: Starting reversing speed range, m/s (the stroke needed is smallest near 1-1.2 m/s).
SPEED_RANGE = (0.9, 1.2)
#: Size of the starting perturbation (omega in rad/s, alpha_k in rad) for one trailer: the
#: vector (omega, alpha_1..alpha_n) is drawn uniformly on the sphere of radius
#: PERTURBATION * n**-PERTURBATION_EXPONENT. The stroke needed per unit of perturbation
#: grows about as fast as that radius shrinks with the number of trailers.
PERTURBATION = 0.064
PERTURBATION_EXPONENT = 1.1
#: Minimum reversing speed, m/s: the episode fails when -u drops below it.
MIN_REVERSE_SPEED = 0.3


class ReverseV1Core(ReverseCore):
    """Batched task logic of Reverse-v1: slower, smaller starts and a minimum reversing speed."""

    version = 1
    baselines = ("zero", "random", "lqr", "mpc")
    #: Starting reversing speed range (m/s) and the half-widths of the perturbations.
    speed_range: ClassVar[tuple[float, float]] = SPEED_RANGE
    #: Radius of the starting perturbation with one trailer (see PERTURBATION).
    perturbation: ClassVar[float] = PERTURBATION
    #: The episode fails when the reversing speed -u drops below this (m/s).
    min_reverse_speed: ClassVar[float] = MIN_REVERSE_SPEED

    @classmethod
    def perturbation_radius(cls, n_trailers: int) -> float:
        """Radius of the starting (omega, alpha) perturbation: ``perturbation * n**-1.1``."""
        return float(cls.perturbation * max(n_trailers, 1) ** -PERTURBATION_EXPONENT)

    def _reset_row(self, i: int, rng: np.random.Generator) -> None:
        z = self.z[i]
        z[0] = -rng.uniform(*self.speed_range)
        direction = rng.standard_normal(self.n + 1)
        z[1 : 2 + self.n] = self.perturbation_radius(self.n) * direction / np.linalg.norm(direction)

    def _stopped_reversing(self) -> np.ndarray:
        return self.z[:, 0] > -self.min_reverse_speed


class ReverseV1Env(ReverseEnv):
    """Reverse-v1 (docstring written below)."""

    core_class = ReverseV1Core
