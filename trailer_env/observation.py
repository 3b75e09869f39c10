"""The observation options: ``observation="flat"`` (default) or ``"trailers"``.

``"flat"`` is the scene's Box, whose length grows with n (documented in each scene's
docstring; padded to ``high`` trailers, mask last, with ``n_trailers=(low, high)``:
:mod:`trailer_env.mixed`). ``"trailers"`` gives the same numbers as a
:class:`gymnasium.spaces.Dict` whose shapes do not depend on n, for policies that read
the convoy trailer by trailer with weights shared across trailers (SB3's
``MultiInputPolicy``, TorchRL's ``Composite``)::

    env = gym.make("trailer_env/Reverse-v1", n_trailers=3, observation="trailers")
    obs, info = env.reset(seed=0)
    obs["body"], obs["trailers"], obs["mask"]  # (4,), (8, 2), (8,)

With ``M = max_trailers`` (default 8), ``m`` mass features (2 on the rail, 4 planar),
the scene's ``T`` task features and ``P`` parameter features (7 with
``observe_params=True``, else 0), all float32:

===============  ============  ==========================================================
key              shape         value
===============  ============  ==========================================================
``body``         (2+m+T+P,)    u, omega, then the flat observation's entries after the
                               hitch angles: the mass's features, the task features,
                               the parameter features, in the flat order
``trailers``     (M, 2)        row k-1 (trailer k, counted from the cart): sin(alpha_k),
                               cos(alpha_k) for k <= n; zeros for k > n
``mask``         (M,)          1 for k <= n, 0 beyond
===============  ============  ==========================================================

So ``body[0:2]`` is flat[0:2] and ``body[2:]`` is flat[2n+2:] (without the padded
layout's mask), ``trailers[:n, 0]`` is flat[2:n+2] and ``trailers[:n, 1]`` flat[n+2:2n+2].
Each trailer row holds its hitch angle's sine and cosine only: its place in the chain
is its row (a policy that reads the rows in order knows it), and a feature such as
``k / n`` would give the same trailer another value at every n, which is what a policy
trained on a few n must not depend on to act at an n it never saw.

The dict is built from the flat observation by :func:`trailers_observation`, a pure
rearrangement (one source of truth): the vector env and the SB3 adapter still replay
single environments bit for bit, and a row of a mixed-n batch whose episode has n
trailers equals the observation of an env made with ``n_trailers=n`` (same
``max_trailers``) in the same state.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from dynamics.params import MAX_TRAILERS, bounded_integer, one_of

#: The values of the ``observation`` keyword.
OBSERVATIONS = ("flat", "trailers")
#: Trailer slots of ``observation="trailers"`` when ``max_trailers`` is not given.
DEFAULT_MAX_TRAILERS = 8
#: Features per trailer row: sin(alpha_k), cos(alpha_k).
TRAILER_FEATURES = 2

#: An observation as the environments return it: the flat Box's array, or the dict of
#: ``observation="trailers"``.
Observation = np.ndarray | dict[str, np.ndarray]


def checked_observation(observation: object, max_trailers: object, n_trailers: int) -> int | None:
    """Validate the ``observation`` and ``max_trailers`` keywords; returns ``max_trailers``
    (the default filled in for "trailers", None for "flat"). Changes nothing.

    Raises:
        TypeError: If ``observation`` is not a str or ``max_trailers`` not an integer.
        ValueError: If ``observation`` is not one of :data:`OBSERVATIONS` (naming them),
            ``max_trailers`` is given with "flat", or is outside ``n_trailers .. 256``.
    """
    one_of("observation", observation, OBSERVATIONS)
    if observation == "flat":
        if max_trailers is not None:
            raise ValueError(
                "max_trailers applies to observation='trailers' only (the flat observation "
                f"holds n_trailers = {n_trailers}); got max_trailers = {max_trailers!r}"
            )
        return None
    if max_trailers is None:
        max_trailers = DEFAULT_MAX_TRAILERS
        given = " (the default)"
    else:
        given = ""
    slots = bounded_integer("max_trailers", max_trailers, 1, MAX_TRAILERS)
    if slots < n_trailers:
        raise ValueError(
            f"max_trailers = {slots}{given} holds fewer trailers than n_trailers = "
            f"{n_trailers}; pass max_trailers >= {n_trailers}"
        )
    return slots


def flat_observation(obs: Observation, what: str) -> np.ndarray:
    """``obs`` itself when it is the flat observation (an array).

    Raises:
        TypeError: If it is the dict of ``observation="trailers"``, naming ``what`` (the
            consumer that reads flat observations).
    """
    if isinstance(obs, dict):
        raise TypeError(
            f"{what} reads the flat observation; make the environment with "
            "observation='flat' (a policy may rearrange it with "
            "trailer_env.observation.trailers_observation)"
        )
    return obs


def trailers_observation(
    flat: np.ndarray, n: int, max_trailers: int, *, padded: bool = False
) -> dict[str, np.ndarray]:
    """The ``observation="trailers"`` dict of flat observations (see the module docstring).

    Args:
        flat: One observation (D,) or a batch (B, D): of a scene made with
            ``n_trailers=n`` (``padded=False``), or in the padded layout of
            ``n_trailers=(low, n)`` whose last n entries are the mask (``padded=True``,
            :mod:`trailer_env.mixed`).
        n: The trailers the layout holds.
        max_trailers: Trailer slots of the result, >= n.
        padded: Whether ``flat`` is the padded layout (its mask is copied) rather than one
            n's (the first n slots are real).

    Returns:
        New float32 arrays ``body`` (..., D - 2n; D - 3n when padded), ``trailers``
        (..., max_trailers, 2) and ``mask`` (..., max_trailers) (one fewer axis for one
        observation).

    Raises:
        ValueError: If ``flat`` is not 1-D or 2-D, is too short for n trailers, or
            ``max_trailers < n``.
    """
    obs = np.asarray(flat, dtype=np.float32)
    if obs.ndim not in (1, 2):
        raise ValueError(f"flat must be one observation or a batch (1-D or 2-D), got {obs.shape}")
    if not 0 <= n <= max_trailers:
        raise ValueError(f"n = {n} trailers do not fit max_trailers = {max_trailers}")
    batch = obs.reshape(-1, obs.shape[-1])
    tail = batch.shape[1] - 2 - (3 if padded else 2) * n
    if tail < 0:
        raise ValueError(f"observations of width {batch.shape[1]} hold fewer than {n} trailers")
    size = batch.shape[0]
    body = np.empty((size, 2 + tail), dtype=np.float32)
    body[:, :2] = batch[:, :2]
    body[:, 2:] = batch[:, 2 + 2 * n : 2 + 2 * n + tail]
    trailers = np.zeros((size, max_trailers, TRAILER_FEATURES), dtype=np.float32)
    trailers[:, :n, 0] = batch[:, 2 : 2 + n]
    trailers[:, :n, 1] = batch[:, 2 + n : 2 + 2 * n]
    mask = np.zeros((size, max_trailers), dtype=np.float32)
    mask[:, :n] = batch[:, 2 + 2 * n + tail :] if padded else 1.0
    if obs.ndim == 1:
        return {"body": body[0], "mask": mask[0], "trailers": trailers[0]}
    return {"body": body, "mask": mask, "trailers": trailers}


class ObservationView:
    """How an environment presents its core's flat observations: as they are ("flat") or
    rearranged by :func:`trailers_observation` ("trailers").

    Args:
        observation: "flat" or "trailers" (validated by :func:`checked_observation`).
        max_trailers: Trailer slots ("trailers"), None for "flat".
        n: Trailers of the core's layout (the range's ``high`` for a padded one).
        padded: Whether the core's observations are the padded layout of a range.
        bounds: The flat observation's lower and upper bounds.

    Attributes:
        space: The observation space of one environment.
    """

    def __init__(
        self,
        observation: str,
        max_trailers: int | None,
        n: int,
        padded: bool,
        bounds: tuple[np.ndarray, np.ndarray],
    ) -> None:
        self.kind = observation
        self.n = n
        self.padded = padded
        low, high = bounds
        self.space: spaces.Box | spaces.Dict
        if observation == "flat" or max_trailers is None:
            self.max_trailers = None
            self.space = spaces.Box(low, high, dtype=np.float32)
            return
        self.max_trailers = max_trailers
        body_low = trailers_observation(low, n, max_trailers, padded=padded)["body"]
        body_high = trailers_observation(high, n, max_trailers, padded=padded)["body"]
        shape = (max_trailers, TRAILER_FEATURES)
        self.space = spaces.Dict(
            {
                "body": spaces.Box(body_low, body_high, dtype=np.float32),
                "mask": spaces.Box(0.0, 1.0, (max_trailers,), dtype=np.float32),
                "trailers": spaces.Box(-1.0, 1.0, shape, dtype=np.float32),
            }
        )

    def batch(self, obs: np.ndarray) -> Observation:
        """The observations of a batch (B, D) as the environments return them (new arrays)."""
        if self.max_trailers is None:
            return obs.copy()
        return trailers_observation(obs, self.n, self.max_trailers, padded=self.padded)

    def row(self, obs: np.ndarray, i: int) -> Observation:
        """Row ``i``'s observation (new arrays)."""
        if self.max_trailers is None:
            return obs[i].copy()
        return trailers_observation(obs[i], self.n, self.max_trailers, padded=self.padded)
