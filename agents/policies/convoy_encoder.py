"""A features extractor that reads the convoy trailer by trailer (imports torch and SB3).

:class:`ConvoyEncoder` is an SB3 ``BaseFeaturesExtractor`` for the Dict observation of
``observation="trailers"`` (:mod:`trailer_env.observation`): ``body`` (cart, mass, task
and parameter features), ``trailers`` (max_trailers, 2) rows of (sin alpha_k, cos alpha_k)
and ``mask``. Its weights do not depend on n: a policy built on n = 2 acts with any
n <= max_trailers. Use it with ``MultiInputPolicy``::

    from stable_baselines3 import PPO
    from trailer_env.sb3 import ConvoySB3VecEnv
    from agents.policies.convoy_encoder import ConvoyEncoder

    venv = ConvoySB3VecEnv("trailer_env/Reverse-v1", 64, n_trailers=(1, 3),
                           observation="trailers")
    PPO("MultiInputPolicy", venv,
        policy_kwargs=dict(features_extractor_class=ConvoyEncoder)).learn(100_000)

In a hyperparameter file: ``policy: MultiInputPolicy`` and ``policy_kwargs: "dict(
features_extractor_class=ConvoyEncoder, features_extractor_kwargs=dict(hidden=64))"``
(:func:`agents.training.config.parse_policy_kwargs` knows the name), and saved models
load without unpickling (:func:`agents.artifacts.sb3_zip.safe_custom_objects` is given
:data:`agents.policies.extractors` 's table).
"""

from __future__ import annotations

import torch
from gymnasium import spaces
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

from agents.policies.convoy_order import check_direction

#: The factor on the centred trailer features (see :class:`ConvoyEncoder`).
DEFAULT_TRAILER_SCALE = 10.0


class ConvoyEncoder(BaseFeaturesExtractor):
    """A GRU pass along the convoy, from the cart to the last trailer, beside an MLP of the body.

    Why a recurrent pass: a convoy is a chain, trailer k hitched to body k - 1, and its
    dynamics propagate along it (each hitch angle's rate depends on the one before it,
    docs/physics.md section 3), so the order of the trailers matters and a set encoder
    (which ignores it) would have to relearn it from position features. A GRU reads the
    trailers in the chain's order with one cell shared by all of them, so trailer k
    needs no position feature and a convoy longer than any seen in training is the same
    recurrence run for more steps; attention with position embeddings would meet
    positions it never trained at n it never saw. The recurrence starts from the cart:
    its initial state is a layer of the body, so each trailer is read in the context of
    the cart's speed and turning rate.

    ``direction="tail_first"`` reads the chain the other way, from the last trailer to
    the one behind the cart (the order of a backstepping design for reversing, where each
    body's wanted angle follows from the one behind it): both ends of the pass are then
    the same bodies at every n (it starts at the last trailer and ends next to the cart,
    where the actuator is), and a longer convoy adds steps in the middle. ``"both"`` runs
    the two passes with separate cells and concatenates their last states.

    Forward, for a batch: ``h_0 = tanh(W_0 body + b_0)``; for each slot k,
    ``h_k = GRUCell(x_k, h_(k-1))`` where ``mask_k = 1`` and ``h_k = h_(k-1)`` where it is
    0, with ``x_k = trailer_scale * (sin alpha_k, cos alpha_k - 1)``; the features are
    ``[h_M, tanh(W_b body + b_b)]`` (``hidden + body_hidden`` values). Masked slots are
    skipped exactly (``torch.where``), so what a padded slot holds changes nothing, and
    n = 0 gives ``h_0``. ``"tail_first"`` runs the slots from M down to 1 with its own
    ``W_0`` and cell; ``"both"`` gives ``[h_M, h'_1, body layer]``
    (``2 hidden + body_hidden`` values).

    Inputs: the trailer features are centred on the straight convoy and scaled by
    ``trailer_scale`` (default 10) because the hitch angles of a nearly straight
    convoy are a few hundredths of a radian, inputs too small to learn from quickly (the
    reason the flat policies normalise observations, agents/hyperparams/ppo.yml). A
    ``VecNormalize`` cannot do it for the trailers: its statistics are per slot, and a
    slot never filled in training (k > 3 when training on n = 1..3) would be divided by
    a variance of zero at n = 4. The body may be normalised by ``VecNormalize`` with
    ``norm_obs_keys=["body"]``; the mask must never be.

    Args:
        observation_space: The Dict space of ``observation="trailers"``.
        hidden: Size of the GRU's state.
        body_hidden: Width of the body's layer.
        trailer_scale: Factor on the centred trailer features (> 0).
        direction: One of :data:`~agents.policies.convoy_order.CONVOY_DIRECTIONS`
            (default ``"cart_first"``, the order of every model saved before the option).

    Raises:
        TypeError: If ``observation_space`` is not that Dict space, or ``direction`` not a str.
        ValueError: If a size is not a positive integer, the scale not a positive number
            or ``direction`` not one of the directions.
    """

    def __init__(
        self,
        observation_space: spaces.Dict,
        hidden: int = 64,
        body_hidden: int = 64,
        trailer_scale: float = DEFAULT_TRAILER_SCALE,
        direction: str = "cart_first",
    ) -> None:
        if not isinstance(observation_space, spaces.Dict) or set(observation_space.spaces) != {
            "body",
            "mask",
            "trailers",
        }:
            raise TypeError(
                "ConvoyEncoder needs the Dict observation of observation='trailers' (keys "
                f"body, mask, trailers), got {observation_space}"
            )
        for name, value in (("hidden", hidden), ("body_hidden", body_hidden)):
            if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 4096:
                raise ValueError(f"{name} must be an integer in 1..4096, got {value!r}")
        if (
            isinstance(trailer_scale, bool)
            or not isinstance(trailer_scale, (int, float))
            or not 0.0 < trailer_scale < float("inf")
        ):
            raise ValueError(f"trailer_scale must be a positive number, got {trailer_scale!r}")
        check_direction("direction", direction)
        passes = 2 if direction == "both" else 1
        super().__init__(observation_space, features_dim=passes * hidden + body_hidden)
        body_space = observation_space["body"]
        trailer_space = observation_space["trailers"]
        assert body_space.shape is not None and trailer_space.shape is not None
        body_dim = int(body_space.shape[0])
        self.trailer_scale = float(trailer_scale)
        self.direction = direction
        features = int(trailer_space.shape[1])
        # "cart_first" keeps the names and the order of creation (so the initial weights
        # drawn from a seed) of the models saved before the option.
        if direction != "tail_first":
            self.start = nn.Sequential(nn.Linear(body_dim, hidden), nn.Tanh())
        self.body = nn.Sequential(nn.Linear(body_dim, body_hidden), nn.Tanh())
        if direction != "tail_first":
            self.cell = nn.GRUCell(features, hidden)
        if direction != "cart_first":
            self.tail_start = nn.Sequential(nn.Linear(body_dim, hidden), nn.Tanh())
            self.tail_cell = nn.GRUCell(features, hidden)
        # cos(alpha) - 1: the straight convoy at the origin of every input.
        self.centre: torch.Tensor
        self.register_buffer("centre", torch.tensor([0.0, 1.0]), persistent=False)

    def forward(self, observations: dict[str, torch.Tensor]) -> torch.Tensor:
        body = observations["body"]
        present = observations["mask"] > 0.5
        inputs = (observations["trailers"] - self.centre) * self.trailer_scale
        # Slots past the batch's longest convoy are skipped: they would leave every state
        # as it is.
        filled = torch.nonzero(present.any(dim=0))
        slots = int(filled.max()) + 1 if filled.numel() else 0
        states = []
        if self.direction != "tail_first":
            state = self.start(body)
            for k in range(slots):
                state = torch.where(present[:, k : k + 1], self.cell(inputs[:, k], state), state)
            states.append(state)
        if self.direction != "cart_first":
            state = self.tail_start(body)
            for k in reversed(range(slots)):
                state = torch.where(
                    present[:, k : k + 1], self.tail_cell(inputs[:, k], state), state
                )
            states.append(state)
        return torch.cat([*states, self.body(body)], dim=1)
