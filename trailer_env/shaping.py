"""Reward shaping: the shaped reward of :class:`trailer_env.core.ShapedCore`, written once for
every path, and potential-based shaping of any scene by a potential of its state.

Potential-based shaping adds ``gamma Phi(s') - Phi(s)`` to a scene's reward
(:func:`shaped_return_step`); :class:`LQRPotential` is the potential the project offers,
:class:`trailer_env.wrappers.PotentialShaping` applies it to one env and
:class:`trailer_env.sb3.PotentialShapingVecEnv` to an SB3 batch (``agents.train --shaping
lqr``). The scene's own reward, its success and its episode statistics are unchanged.

:func:`shaped_reward` is the formula for one row; scenes whose reward is computed inside
their compiled step (Coast) call it there, and :meth:`ShapedCore._reward` calls it through
:func:`shaped_rewards` for the whole batch, so the fused and unfused steps share it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from dynamics.jit import cached_njit
from dynamics.params import bounded_real

if TYPE_CHECKING:
    from trailer_env.settings import EnvSettings


#: Indices of the penalty vector of :func:`shaped_reward`
#: (:attr:`trailer_env.core.ShapedCore.shaping_penalties`, built by :func:`penalty_vector`).
TIME_PENALTY, BAND_PENALTY, SUCCESS_BONUS, FOLD_PENALTY, FAILURE_PENALTY = range(5)


def penalty_vector(
    time_penalty: float,
    band_penalty: float,
    success_bonus: float,
    fold_penalty: float,
    failure_penalty: float,
) -> np.ndarray:
    """The penalty vector of :func:`shaped_reward`: each constant at its named index."""
    penalties = np.empty(5, dtype=np.float64)
    penalties[TIME_PENALTY] = time_penalty
    penalties[BAND_PENALTY] = band_penalty
    penalties[SUCCESS_BONUS] = success_bonus
    penalties[FOLD_PENALTY] = fold_penalty
    penalties[FAILURE_PENALTY] = failure_penalty
    return penalties


@cached_njit(nogil=True)
def shaped_reward(
    potential: float,
    previous: float,
    cost: float,
    success: bool,
    jackknifed: bool,
    failed: bool,
    penalties: np.ndarray,
) -> float:
    """``potential - previous - time_penalty - band_penalty * cost + success_bonus * success
    - fold_penalty * jackknifed - failure_penalty * failed``.

    ``penalties`` is :attr:`trailer_env.core.ShapedCore.shaping_penalties` (from
    :func:`penalty_vector`), indexed by :data:`TIME_PENALTY` .. :data:`FAILURE_PENALTY`.
    """
    return (
        potential
        - previous
        - penalties[TIME_PENALTY]
        - penalties[BAND_PENALTY] * cost
        + penalties[SUCCESS_BONUS] * success
        - penalties[FOLD_PENALTY] * jackknifed
        - penalties[FAILURE_PENALTY] * failed
    )


@cached_njit()
def shaped_rewards(
    potential: np.ndarray,
    previous: np.ndarray,
    cost: np.ndarray,
    success: np.ndarray,
    jackknifed: np.ndarray,
    failed: np.ndarray,
    penalties: np.ndarray,
    out: np.ndarray,
) -> None:
    """:func:`shaped_reward` of every row into ``out``."""
    for i in range(out.shape[0]):
        out[i] = shaped_reward(
            potential[i], previous[i], cost[i], success[i], jackknifed[i], failed[i], penalties
        )


#: Default of :class:`LQRPotential`'s ``reference``: the regulator's cost-to-go of a state
#: about five times smaller than Reverse-v1's typical start (median 0.46-0.62 for n = 1-3),
#: so the potential is flat near the straight convoy and logarithmic beyond.
LQR_REFERENCE = 0.1


class LQRPotential:
    """``Phi(s) = -scale * log(1 + x^T P(u) x / reference)``: the logarithm of the LQR's
    cost-to-go (:meth:`trailer_env.controllers.LQRController.cost_to_go`).

    A convoy drifting away along its unstable modes (rates of about ``|u| / l``) makes the
    cost-to-go grow exponentially and so the potential fall at a steady rate, which the
    shaping term ``gamma Phi(s') - Phi(s)`` turns into a reward of about
    ``-2 lambda dt scale`` per step; one being straightened earns as much. Scenes whose
    observation starts with the common part (all of them) accept it.

    Args:
        settings: The environment's settings (one count of trailers).
        scale: Reward units per unit of ``log`` cost-to-go, > 0.
        reference: Cost-to-go at which the logarithm takes over, > 0.
    """

    def __init__(
        self, settings: EnvSettings, scale: float = 1.0, reference: float = LQR_REFERENCE
    ) -> None:
        # scipy (the Riccati solver) is imported by the controllers only when a potential is built.
        from trailer_env.controllers import LQRController

        self.scale = bounded_real("scale", scale, 0.0, 1e6, low_open=True)
        self.reference = bounded_real("reference", reference, 0.0, 1e6, low_open=True)
        self.regulator = LQRController(settings)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The potential (B,) of a batch of observations (B, obs_dim)."""
        cost = self.regulator.cost_to_go(obs)
        return -self.scale * np.log1p(cost / self.reference)


#: Potentials by name (:func:`make_potential`).
POTENTIALS = {"lqr": LQRPotential}


def make_potential(name: str, settings: EnvSettings, **kwargs: float) -> LQRPotential:
    """The potential ``name`` (a key of :data:`POTENTIALS`) for ``settings``.

    Raises:
        ValueError: An unknown name (naming the known ones) or a bad value.
        TypeError: An unknown keyword or a bad type.
    """
    if name not in POTENTIALS:
        raise ValueError(f"unknown potential {name!r}; potentials: {sorted(POTENTIALS)}")
    try:
        return POTENTIALS[name](settings, **kwargs)
    except TypeError as error:
        if "unexpected keyword" in str(error):
            raise TypeError(f"potential {name!r}: {error}") from None
        raise


def shaped_return_step(
    reward: np.ndarray,
    potential_before: np.ndarray,
    potential_after: np.ndarray,
    terminated: np.ndarray,
    gamma: float,
) -> np.ndarray:
    """Potential-based shaping (Ng, Harada and Russell 1999): ``reward + gamma Phi(s') -
    Phi(s)``, with ``Phi = 0`` on a terminal state, so the optimal policies of the
    discounted task are unchanged. A truncated step passes the state it reached (not the
    next episode's start) as ``s'``, because the episode goes on beyond the cut."""
    after = np.where(terminated, 0.0, potential_after)
    return np.asarray(reward, dtype=np.float64) + gamma * after - potential_before


def check_gamma(gamma: object) -> float:
    """``gamma`` as a float in (0, 1] (TypeError or ValueError otherwise)."""
    return bounded_real("gamma", gamma, 0.0, 1.0, low_open=True)
